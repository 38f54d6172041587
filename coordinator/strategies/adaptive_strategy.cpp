#include "adaptive_strategy.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "allocation.h"
#include "bands.h"
#include "exact_quotient.h"
#include "vec3.h"

namespace aliquot {

namespace {

double pixel_value(const Accumulator& merged, size_t i) {
    double rgb[3];
    merged.mean(i, rgb);
    return luminance(rgb[0], rgb[1], rgb[2]);
}

}  // namespace

AdaptiveStrategy::AdaptiveStrategy(const StrategyParams& p, uint32_t width,
                                   uint32_t height)
    : width_(width),
      height_(height),
      budget_(sample_budget(p, size_t(width) * height)),
      bucket_size_(std::max<uint32_t>(p.bucket_size, 1)),
      cap_(spp_cap(p)),
      max_variance_(p.max_variance),
      alpha_(p.alpha) {
    // A budget below the initial pass shrinks the pass, so the budget is never exceeded.
    const uint64_t fit = budget_ / (uint64_t(width) * height);
    initial_spp_ = uint32_t(std::min<uint64_t>({p.initial_spp, fit, cap_}));
}

std::vector<PixelRect> AdaptiveStrategy::grid() const {
    std::vector<PixelRect> cells;
    for (uint32_t y = 0; y < height_; y += bucket_size_)
        for (uint32_t x = 0; x < width_; x += bucket_size_)
            cells.push_back({x, y, std::min(bucket_size_, width_ - x),
                             std::min(bucket_size_, height_ - y)});
    return cells;
}

double AdaptiveStrategy::bucket_variance(const Accumulator& merged, const PixelRect& r) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (uint32_t y = r.y; y < r.y + r.height; ++y) {
        for (uint32_t x = r.x; x < r.x + r.width; ++x) {
            const double v = pixel_value(merged, size_t(y) * merged.width() + x);
            lo = std::min(lo, v);
            hi = std::max(hi, v);
        }
    }
    return r.size() ? hi - lo : 0.0;
}

std::vector<double> AdaptiveStrategy::bucket_weights(const std::vector<double>& variances,
                                                     double max_variance, double alpha) {
    std::vector<double> weights(variances.size(), 1.0);
    if (alpha == 0) return weights;
    const double neg_inf = -std::numeric_limits<double>::infinity();
    std::vector<double> log_ratio(variances.size());
    double top = neg_inf;
    for (size_t b = 0; b < variances.size(); ++b) {
        const double v = variances[b];
        // A non-finite range (sums that overflowed) counts as saturated, never as NaN.
        if (!std::isfinite(v))
            log_ratio[b] = 0;
        else if (v <= 0)
            log_ratio[b] = neg_inf;
        else
            log_ratio[b] = std::min(0.0, std::log(v) - std::log(max_variance));
        top = std::max(top, log_ratio[b]);
    }
    for (size_t b = 0; b < variances.size(); ++b)
        weights[b] = top == neg_inf ? 0.0 : std::exp(alpha * (log_ratio[b] - top));
    return weights;
}

void AdaptiveStrategy::plan_remainder() {
    const std::vector<PixelRect> cells = grid();
    const size_t pixels = size_t(width_) * height_;
    std::vector<double> weight(pixels);
    for (size_t b = 0; b < cells.size(); ++b)
        for (uint32_t y = cells[b].y; y < cells[b].y + cells[b].height; ++y)
            std::fill_n(weight.begin() + size_t(y) * width_ + cells[b].x, cells[b].width,
                        weights_[b]);
    std::vector<uint32_t> room(pixels, cap_ - initial_spp_);
    // Each pixel's share is proportional to its bucket's weight, so a bucket's total is
    // proportional to weight * pixel count, as in the seed.
    extra_ = apportion(weight, double(remainder_), room);
    uint64_t given = 0;
    for (uint32_t e : extra_) given += e;
    if (given < remainder_) {
        // All weights 0 (a flat image) or the weighted pixels at max_spp: the rest goes
        // evenly to every pixel that can still take samples.
        std::vector<double> even(pixels);
        for (size_t i = 0; i < pixels; ++i) {
            room[i] -= extra_[i];
            even[i] = room[i] > 0 ? 1.0 : 0.0;
        }
        const std::vector<uint32_t> more =
            apportion(even, double(remainder_ - given), room);
        for (size_t i = 0; i < pixels; ++i) {
            extra_[i] += more[i];
            given += more[i];
        }
    }
    unspent_ = remainder_ - given;
    // The remainder is decided once, after the initial pass (as in the seed), and
    // delivered in rounds of about round_samples(budget) (an eighth of the budget, at
    // least kRoundSamples) so that progress, per-round error and checkpoints stay
    // frequent while a pixel is merged a few times, not once every kRoundSamples; the
    // decision does not depend on how it is delivered, only the sums' grouping does.
    const uint64_t round = round_samples(budget_);
    deliveries_ = uint32_t(std::max<uint64_t>(1, (given + round - 1) / round));
}

void AdaptiveStrategy::deliver(uint64_t r, std::vector<uint32_t>& spp) const {
    // Delivery r of K gives floor(a (r+1) / K) - floor(a r / K): the parts add up to a.
    // In bands, and without a 64-bit division a pixel (most of this pass's time at
    // 1920x1080).
    spp.resize(size_t(width_) * height_);
    const ExactQuotient quotient(deliveries_);
    for_each_band(spp.size(), kBandPixels, [&](size_t, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i)
            spp[i] = uint32_t(quotient(uint64_t(extra_[i]) * (r + 1)) -
                              quotient(uint64_t(extra_[i]) * r));
    });
}

std::function<void()> AdaptiveStrategy::take_work_ahead() {
    return std::exchange(work_ahead_, nullptr);
}

std::optional<Round> AdaptiveStrategy::next_round(const Accumulator& merged) {
    if (work_ahead_) std::exchange(work_ahead_, nullptr)();  // not taken: done here
    const size_t pixels = size_t(width_) * height_;
    if (phase_ == Phase::initial) {
        phase_ = Phase::allocate;
        if (initial_spp_ > 0)
            return Round{rounds_++, std::vector<uint32_t>(pixels, initial_spp_)};
    }
    if (phase_ == Phase::allocate) {
        const std::vector<PixelRect> cells = grid();
        variances_.resize(cells.size());
        // Each bucket's range on its own, on the pool's threads (bands.h): a pass over
        // every pixel's sums, ~25 ms of this round end's ~150 at 1920x1080 on one
        // thread. A band of 64 buckets is 16 K pixels at the default 16x16.
        for_each_band(cells.size(), 64, [&](size_t, size_t begin, size_t end) {
            for (size_t b = begin; b < end; ++b)
                variances_[b] = bucket_variance(merged, cells[b]);
        });
        weights_ = bucket_weights(variances_, max_variance_, alpha_);
        const uint64_t spent = merged.total_samples();
        remainder_ = budget_ > spent ? budget_ - spent : 0;
        plan_remainder();
        phase_ = Phase::deliver;
    }
    if (phase_ == Phase::deliver && delivered_ < deliveries_) {
        Round round{rounds_, {}};
        // The very vector made ahead, whose jobs may be out already.
        if (ahead_.empty())
            deliver(delivered_, round.spp);
        else
            round.spp = std::exchange(ahead_, {});
        ++delivered_;
        if (round.total() > 0) {
            ++rounds_;
            if (delivered_ < deliveries_)
                work_ahead_ = [this, r = uint64_t(delivered_)] { deliver(r, ahead_); };
            return round;
        }
    }
    phase_ = Phase::done;
    return std::nullopt;
}

std::vector<Bucket> AdaptiveStrategy::buckets() const {
    const std::vector<PixelRect> cells = grid();
    std::vector<Bucket> out(cells.size());
    for (size_t b = 0; b < cells.size(); ++b)
        out[b] = {cells[b], b < variances_.size() ? variances_[b] : 0.0, false};
    return out;
}

nlohmann::json AdaptiveStrategy::outcome() const {
    return {{"budget", budget_},
            {"initial_spp", initial_spp_},
            {"remainder", remainder_},
            {"unspent", unspent_}};
}

nlohmann::json AdaptiveStrategy::save_state() const {
    return {{"phase", int(phase_)},      {"variances", variances_},
            {"weights", weights_},       {"remainder", remainder_},
            {"deliveries", deliveries_}, {"delivered", delivered_},
            {"rounds", rounds_}};
}

void AdaptiveStrategy::restore_state(const nlohmann::json& state) {
    const int phase = state.at("phase").get<int>();
    if (phase < 0 || phase > int(Phase::done))
        throw std::invalid_argument("adaptive state: unknown phase");
    std::vector<double> variances = state.at("variances").get<std::vector<double>>();
    std::vector<double> weights = state.at("weights").get<std::vector<double>>();
    const bool planned = Phase(phase) == Phase::deliver || Phase(phase) == Phase::done;
    if (planned && weights.size() != grid().size())
        throw std::invalid_argument(
            "adaptive state: bucket count does not match the image");
    phase_ = Phase(phase);
    variances_ = std::move(variances);
    weights_ = std::move(weights);
    remainder_ = state.at("remainder").get<uint64_t>();
    rounds_ = state.at("rounds").get<uint32_t>();
    work_ahead_ = nullptr;
    ahead_.clear();
    // The allocation is a function of the weights and the remainder, so it is recomputed
    // rather than stored per pixel.
    if (planned) plan_remainder();
    deliveries_ = state.at("deliveries").get<uint32_t>();
    delivered_ = state.at("delivered").get<uint32_t>();
}

}  // namespace aliquot
