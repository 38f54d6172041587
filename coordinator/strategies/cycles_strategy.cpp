#include "cycles_strategy.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "allocation.h"
#include "bands.h"
#include "exact_quotient.h"

namespace aliquot {

namespace {

constexpr uint32_t kDefaultMaxSpp = 4096;  // Cycles' default render samples

// Keeps sqrt(intensity) away from 0 so a black pixel's error is finite (Cycles adds a
// small constant for the same reason).
constexpr double kIntensityEpsilon = 1e-4;

// judged_at_ for a pixel never judged, or judged at more samples than a uint32_t holds
// (judged again every round then, as before).
constexpr uint32_t kNeverJudged = UINT32_MAX;

// Rows in one band of a pass over rows: about kBandPixels pixels.
size_t rows_per_band(uint32_t width) {
    return std::max<size_t>(1, kBandPixels / std::max(width, 1u));
}

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
    const PixelSums& p = merged.at(i);
    if (p.samples < 2) return std::numeric_limits<double>::infinity();
    // Accumulator::mean's and half_means' arithmetic, the same operations in the same
    // order (so the same bits), on the sums read once, and without the odd half's
    // divisions, which the error does not use: the judgement of every pixel that got
    // samples is most of a round end's own work, and its divisions most of that.
    const double inv = 1.0 / double(p.samples);
    const double n_even = double((p.samples + 1) / 2);
    double difference = 0, intensity = 0;
    for (int c = 0; c < 3; ++c) {
        const double full = (p.even[c] + p.odd[c]) * inv;
        difference += std::abs(full - p.even[c] / n_even);
        intensity += full;
    }
    return difference / (kIntensityEpsilon + std::sqrt(std::max(intensity, 0.0)));
}

std::vector<bool> CyclesStrategy::dilate_unconverged(const std::vector<bool>& converged,
                                                     uint32_t w, uint32_t h) {
    const std::vector<char> below(converged.begin(), converged.end());
    std::vector<char> rows(below.size());
    for (uint32_t y = 0; y < h; ++y)
        dilate_row(&below[size_t(y) * w], &rows[size_t(y) * w], w);
    std::vector<bool> out(converged.size());
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
            out[size_t(y) * w + x] = dilated(rows, x, y, w, h);
    return out;
}

void CyclesStrategy::dilate_row(const char* below, char* rows, uint32_t w) {
    if (w == 0) return;
    if (w == 1) {
        rows[0] = below[0];
        return;
    }
    // Bytes of 0 or 1, and'ed without a branch a pixel (the pass vectorises); the edges,
    // with one neighbour in the row, apart.
    rows[0] = below[0] & below[1];
    for (uint32_t x = 1; x + 1 < w; ++x) rows[x] = below[x - 1] & below[x] & below[x + 1];
    rows[w - 1] = below[w - 2] & below[w - 1];
}

bool CyclesStrategy::dilated(const std::vector<char>& rows, uint32_t x, uint32_t y,
                             uint32_t w, uint32_t h) {
    const size_t i = size_t(y) * w + x;
    return rows[i] && (y == 0 || rows[i - w]) && (y + 1 == h || rows[i + w]);
}

void CyclesStrategy::judge(const Accumulator& merged) {
    const size_t pixels = size_t(width_) * height_;
    if (judged_at_.size() != pixels) {
        judged_at_.assign(pixels, kNeverJudged);
        below_.assign(pixels, 0);
        rows_.assign(pixels, 0);
    }
    // In bands of whole rows on the pool's threads (bands.h): each row's errors, into
    // bytes (two threads must not write bits of one std::vector<bool> word), then the
    // dilation's row pass over it. Only pixels with samples the last judgement did not
    // see are judged: the same bytes as judging all.
    for_each_band(height_, rows_per_band(width_), [&](size_t, size_t row0, size_t row1) {
        for (size_t y = row0; y < row1; ++y) {
            const size_t row = y * width_;
            for (size_t i = row; i < row + width_; ++i) {
                const uint64_t have = merged.samples(i);
                if (have < kNeverJudged && have == judged_at_[i]) continue;
                below_[i] = pixel_error(merged, i) < threshold_;
                judged_at_[i] = have < kNeverJudged ? uint32_t(have) : kNeverJudged;
            }
            dilate_row(&below_[row], &rows_[row], width_);
        }
    });
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
        judge(merged);
        // The dilation's column pass and the plan, in bands of rows; the counts are
        // whole numbers, added in any order.
        const size_t band_rows = rows_per_band(width_);
        const size_t bands = band_count(height_, band_rows);
        // have / step_ without a 64-bit division a pixel (have < max_spp_, a uint32_t).
        const ExactQuotient steps(step_);
        std::vector<size_t> band_done(bands, 0), band_capped(bands, 0);
        for_each_band(height_, band_rows, [&](size_t band, size_t row0, size_t row1) {
            for (uint32_t y = uint32_t(row0); y < row1; ++y) {
                // dilated(), a row at a time: a missing neighbour row (the image's edge)
                // is the row itself.
                const char* here = &rows_[size_t(y) * width_];
                const char* up = y > 0 ? here - width_ : here;
                const char* down = y + 1 < height_ ? here + width_ : here;
                for (uint32_t x = 0; x < width_; ++x) {
                    const size_t i = size_t(y) * width_ + x;
                    const uint64_t have = merged.samples(i);
                    if (up[x] & here[x] & down[x]) {
                        ++band_done[band];
                    } else if (have >= max_spp_) {
                        ++band_capped[band];
                    } else {
                        // The first check falls on a multiple of the step, as Cycles
                        // aligns it.
                        const uint64_t next = (steps(have) + 1) * uint64_t(step_);
                        round.spp[i] =
                            uint32_t(std::min<uint64_t>(next, max_spp_) - have);
                    }
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
    judged_at_.clear();  // the buffers restored with it are judged afresh
    rounds_ = state.at("rounds").get<uint32_t>();
    converged_fraction_ = state.at("converged_fraction").get<double>();
    stopped_by_ = state.at("stopped_by").get<std::string>();
}

}  // namespace aliquot
