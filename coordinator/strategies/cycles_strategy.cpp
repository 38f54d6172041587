#include "cycles_strategy.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "allocation.h"
#include "bands.h"

namespace aliquot {

namespace {

constexpr uint32_t kDefaultMaxSpp = 4096;  // Cycles' default render samples

// Keeps sqrt(intensity) away from 0 so a black pixel's error is finite (Cycles adds a
// small constant for the same reason).
constexpr double kIntensityEpsilon = 1e-4;

}  // namespace

uint32_t CyclesStrategy::automatic_min_samples(double threshold) {
    const double n = std::ceil(16.0 / std::pow(threshold, 0.3));
    return uint32_t(std::clamp(n, 4.0, double(UINT32_MAX)));
}

CyclesStrategy::CyclesStrategy(const StrategyParams& p, uint32_t width, uint32_t height)
    : width_(width),
      height_(height),
      threshold_(p.noise_threshold),
      min_samples_(p.adaptive_min_samples ? p.adaptive_min_samples
                                          : automatic_min_samples(p.noise_threshold)),
      step_(p.adaptive_step),
      max_spp_(p.max_spp ? p.max_spp : kDefaultMaxSpp) {
    const uint64_t pixels = uint64_t(width) * height;
    // Like Dammertz, Cycles aims at a noise level, not a budget: a budget is a cap.
    if (p.budget || p.spp)
        max_samples_ = sample_budget(p, pixels);
    else
        max_samples_ = p.max_samples ? p.max_samples : uint64_t(max_spp_) * pixels;
    min_samples_ = std::min(min_samples_, max_spp_);
}

uint64_t CyclesStrategy::planned_samples() const {
    return std::min(max_samples_, uint64_t(max_spp_) * width_ * height_);
}

double CyclesStrategy::pixel_error(const Accumulator& merged, size_t i) {
    if (merged.samples(i) < 2) return std::numeric_limits<double>::infinity();
    double full[3], even[3], odd[3];
    merged.mean(i, full);
    merged.half_means(i, even, odd);
    double difference = 0, intensity = 0;
    for (int c = 0; c < 3; ++c) {
        difference += std::abs(full[c] - even[c]);
        intensity += full[c];
    }
    return difference / (kIntensityEpsilon + std::sqrt(std::max(intensity, 0.0)));
}

std::vector<bool> CyclesStrategy::dilate_unconverged(const std::vector<bool>& converged,
                                                     uint32_t w, uint32_t h) {
    std::vector<bool> rows(converged.size()), out(converged.size());
    auto at = [w](uint32_t x, uint32_t y) { return size_t(y) * w + x; };
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
            rows[at(x, y)] = converged[at(x, y)] && (x == 0 || converged[at(x - 1, y)]) &&
                             (x + 1 == w || converged[at(x + 1, y)]);
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
            out[at(x, y)] = rows[at(x, y)] && (y == 0 || rows[at(x, y - 1)]) &&
                            (y + 1 == h || rows[at(x, y + 1)]);
    return out;
}

std::optional<Round> CyclesStrategy::next_round(const Accumulator& merged) {
    if (!stopped_by_.empty()) return std::nullopt;
    const size_t pixels = size_t(width_) * height_;
    Round round{rounds_, std::vector<uint32_t>(pixels, 0)};
    if (rounds_ == 0) {
        // Every pixel reaches the minimum before any is judged: the error of a few
        // samples is itself too noisy to stop on.
        std::fill(round.spp.begin(), round.spp.end(), min_samples_);
    } else {
        // The per-pixel errors in bands on the pool's threads (bands.h), into bytes: two
        // threads must not write bits of one std::vector<bool> word.
        std::vector<char> below(pixels);
        for_each_band(pixels, kBandPixels, [&](size_t, size_t begin, size_t end) {
            for (size_t i = begin; i < end; ++i)
                below[i] = pixel_error(merged, i) < threshold_;
        });
        std::vector<bool> converged(below.begin(), below.end());
        converged = dilate_unconverged(converged, width_, height_);
        const size_t bands = band_count(pixels, kBandPixels);
        std::vector<size_t> band_done(bands, 0), band_capped(bands, 0);
        for_each_band(pixels, kBandPixels, [&](size_t band, size_t begin, size_t end) {
            for (size_t i = begin; i < end; ++i) {
                const uint64_t have = merged.samples(i);
                if (converged[i]) {
                    ++band_done[band];
                } else if (have >= max_spp_) {
                    ++band_capped[band];
                } else {
                    // The first check falls on a multiple of the step, as Cycles aligns
                    // it.
                    const uint64_t next = (have / step_ + 1) * uint64_t(step_);
                    round.spp[i] = uint32_t(std::min<uint64_t>(next, max_spp_) - have);
                }
            }
        });
        size_t done = 0, capped = 0;
        for (size_t b = 0; b < bands; ++b) {
            done += band_done[b];
            capped += band_capped[b];
        }
        converged_fraction_ = double(done) / double(pixels);
        if (done + capped == pixels) {
            stopped_by_ = capped ? "max_spp" : "converged";
            return std::nullopt;
        }
    }
    // A round that would pass the cap shrinks to what fits, spread evenly over the active
    // pixels (hash-ordered), and is the last.
    const uint64_t spent = merged.total_samples();
    const uint64_t room = max_samples_ > spent ? max_samples_ - spent : 0;
    if (round.total() > room) {
        std::vector<double> active(pixels);
        for (size_t i = 0; i < pixels; ++i) active[i] = round.spp[i] ? 1.0 : 0.0;
        round.spp = apportion(active, double(room), round.spp);
        stopped_by_ = "max_samples";
        if (round.total() == 0) return std::nullopt;
    }
    ++rounds_;
    return round;
}

nlohmann::json CyclesStrategy::outcome() const {
    return {{"stopped_by", stopped_by_.empty() ? "running" : stopped_by_},
            {"converged_fraction", converged_fraction_},
            {"noise_threshold", threshold_},
            {"min_samples", min_samples_},
            {"rounds", rounds_},
            {"max_spp", max_spp_},
            {"max_samples", max_samples_}};
}

nlohmann::json CyclesStrategy::save_state() const {
    return {{"rounds", rounds_},
            {"converged_fraction", converged_fraction_},
            {"stopped_by", stopped_by_}};
}

void CyclesStrategy::restore_state(const nlohmann::json& state) {
    rounds_ = state.at("rounds").get<uint32_t>();
    converged_fraction_ = state.at("converged_fraction").get<double>();
    stopped_by_ = state.at("stopped_by").get<std::string>();
}

}  // namespace aliquot
