#include "optimal_strategy.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>

#include "allocation.h"
#include "bands.h"
#include "cube_root.h"
#include "sigma_passes.h"

// Why n_i ∝ sigma_i^(2/3). The mean of n_i samples of pixel i has standard deviation
// sigma_i / sqrt(n_i), and for a near-normal error its expected absolute value is
// sqrt(2/pi) times that; so the seed's E (mean absolute error over pixels) is, up to a
// constant,
//     F(n) = sum_i sigma_i / sqrt(n_i).
// Minimise F subject to a budget sum_i c_i n_i = T (optimal: c_i = 1, T = B samples;
// optimal-time: c_i = rays per sample, T = rays). With a Lagrange multiplier lambda,
//     L = sum_i sigma_i n_i^(-1/2) + lambda (sum_i c_i n_i - T),
//     dL/dn_i = -(1/2) sigma_i n_i^(-3/2) + lambda c_i = 0
//     =>  n_i = (sigma_i / (2 lambda c_i))^(2/3)  ∝  (sigma_i / c_i)^(2/3).
// F is convex (n^(-1/2) is), so this stationary point is the minimum; with the floor and
// cap as box constraints the KKT conditions give n_i = clamp(mu w_i, lo, hi), w_i the
// weight above and one mu for all pixels. Without the box, F_opt = (sum
// sigma^(2/3))^(3/2) / sqrt(B) against uniform's (sum sigma) sqrt(N / B); Hölder's
// inequality makes the ratio <= 1. (Squared error, sum sigma^2 / n, would give n ∝ sigma,
// as in Neyman's allocation.)

namespace aliquot {

namespace {

using sigma_passes::box_mean;
using sigma_passes::kImageFactor;
using sigma_passes::median_value;
using sigma_passes::neighbours_mean;
using sigma_passes::sigma_from_neighbourhood;

// Mean rays a sample costs so far; 1 before anything is traced.
double rays_per_sample(const Accumulator& merged) {
    return merged.total_samples() && merged.total_rays()
               ? double(merged.total_rays()) / merged.total_samples()
               : 1.0;
}

}  // namespace

OptimalStrategy::OptimalStrategy(const StrategyParams& p, uint32_t width, uint32_t height,
                                 bool cost_aware)
    : width_(width),
      height_(height),
      budget_(sample_budget(p, size_t(width) * height)),
      // The floor tied to the budget: a share of the mean spp, never below min_spp.
      min_spp_(std::max<uint32_t>(
          p.min_spp, uint32_t(std::min(double(UINT32_MAX),
                                       std::floor(p.floor_fraction * double(budget_) /
                                                  double(std::max<size_t>(
                                                      size_t(width) * height, 1))))))),
      cap_(spp_cap(p)),
      sigma_radius_(p.sigma_radius),
      sigma_prior_(p.sigma_prior),
      sigma_self_out_(p.sigma_self_out),
      steer_rounds_(p.steer_rounds),
      plan_ahead_(p.plan_ahead),
      cost_aware_(cost_aware) {
    min_spp_ = std::min(min_spp_, cap_);  // a floor from the budget never passes max_spp
    const size_t pixels = std::max<size_t>(size_t(width) * height, 1);
    pilot_spp_ = std::min<uint64_t>({min_spp_, budget_ / pixels, cap_});
    // Each half needs two samples for a variance.
    split_pilot_ = pilot_spp_ >= 4 &&
                   double(pilot_spp_) * double(pixels) <= plan_ahead_ * double(budget_);
}

std::vector<double> OptimalStrategy::sigma_estimates(const Accumulator& merged,
                                                     uint32_t radius, uint32_t prior,
                                                     uint32_t self_out) {
    Planning b;
    read_merged(merged, false, {}, b);
    estimate_sigma(b, merged.width(), merged.height(), radius, prior, self_out);
    return std::move(b.sigma);
}

void OptimalStrategy::read_merged(const Accumulator& merged, bool costs,
                                  const std::vector<uint32_t>& in_flight, Planning& b) {
    const size_t n = merged.pixel_count();
    b.variance.resize(n);
    b.samples.resize(n);
    // optimal-time's costs (a pixel's rays per sample, or the image's mean where it has
    // none) are made in the same pass, from the counts the accumulator keeps beside its
    // sums.
    b.mean_cost = rays_per_sample(merged);
    b.cost.resize(costs ? n : 0);
    // Each band's largest finite variance; max is exact in any order.
    std::vector<double> band_largest(band_count(n, kBandPixels), 0.0);
    std::vector<char> band_nonfinite(band_largest.size(), 0);
    for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        double largest = 0;
        bool nonfinite = false;
        for (size_t i = begin; i < end; ++i) {
            const double v = merged.luminance_variance(i);
            b.variance[i] = v;
            const bool finite = std::isfinite(v);
            if (finite) largest = std::max(largest, v);
            nonfinite = nonfinite | !finite;
            const uint64_t samples = merged.samples(i);
            b.samples[i] = samples;
            if (costs) {
                const uint64_t rays = merged.rays(i);
                b.cost[i] =
                    samples && rays ? double(rays) / double(samples) : b.mean_cost;
            }
        }
        band_largest[band] = largest;
        band_nonfinite[band] = nonfinite;
    });
    b.largest = 0;
    for (double l : band_largest) b.largest = std::max(b.largest, l);
    b.nonfinite = std::find(band_nonfinite.begin(), band_nonfinite.end(), 1) !=
                  band_nonfinite.end();
    b.spent = costs ? double(merged.total_rays()) : double(merged.total_samples());
    b.in_flight = in_flight;
}

void OptimalStrategy::estimate_sigma(Planning& b, uint32_t width, uint32_t height,
                                     uint32_t radius, uint32_t prior, uint32_t self_out) {
    std::vector<double>& var = b.variance;
    std::vector<double>& sigma = b.sigma;
    const size_t n = var.size();
    // Sums that overflowed say "very noisy", not NaN (a pass only when there are any).
    if (b.nonfinite)
        for_each_band(n, kBandPixels, [&](size_t, size_t begin, size_t end) {
            for (size_t i = begin; i < end; ++i)
                if (!std::isfinite(var[i])) var[i] = b.largest;
        });
    const double median = median_value(var, b.median_counts, b.median_candidates);
    const auto each_pixel = [&](auto&& f) {
        for_each_band(n, kBandPixels, [&](size_t, size_t begin, size_t end) {
            for (size_t i = begin; i < end; ++i) f(i);
        });
    };
    if (self_out > 0) {
        // Leave-one-out: a pixel's own samples set its mean, so they must not set its
        // count too, or a pixel that missed a heavy tail's rare bright paths looks quiet,
        // gets few samples more and keeps its dark mean (docs/RESULTS.md, "Is `optimal`
        // biased low?"). Its neighbours' variances alone stand for its own; the 3x3
        // median protection is left out (it would read the pixel's own variance back
        // through its neighbours' means), the image floor kept; a mean that overflowed
        // says "as noisy as the noisiest pixel".
        neighbours_mean(var, width, height, self_out, sigma);
        const double largest = std::max(b.largest, kImageFactor * median);
        each_pixel([&](size_t i) {
            sigma[i] = std::sqrt(std::clamp(sigma[i], kImageFactor * median, largest));
        });
        return;
    }
    if (prior > 0) {
        // Shrinkage: the pool is a prior worth `prior` samples, the pixel's own s^2 is
        // worth its (n - 1) degrees of freedom. A pixel whose four samples held one
        // firefly leans on its neighbourhood; one with thousands of samples on itself, so
        // a truly isolated noisy pixel still gets its share once it has been sampled.
        const std::vector<double> pooled =
            box_mean(var, width, height, std::max(radius, 1u));
        sigma.resize(n);
        each_pixel([&](size_t i) {
            const double own = b.samples[i] > 1 ? double(b.samples[i] - 1) : 0.0;
            const double v = (own * var[i] + prior * pooled[i]) / (own + prior);
            sigma[i] = std::sqrt(std::max(v, kImageFactor * median));
        });
        return;
    }
    if (radius > 0) {
        // Pooled: each pixel's variance is the plain mean of its window's sample
        // variances (an unbiased estimate of the window's mean variance). A firefly one
        // pixel drew is spread over the window, so the budget no longer chases that pixel
        // alone and its neighbours, which drew none yet, are not starved. The price: a
        // sharp edge between a noisy and a quiet region is blurred by r pixels.
        const std::vector<double> pooled = box_mean(var, width, height, radius);
        sigma.resize(n);
        each_pixel([&](size_t i) {
            sigma[i] = std::sqrt(std::max(pooled[i], kImageFactor * median));
        });
        return;
    }
    sigma_from_neighbourhood(var, width, height, kImageFactor * median, sigma);
}

std::vector<double> OptimalStrategy::optimal_counts(const std::vector<double>& weights,
                                                    const std::vector<double>& costs,
                                                    double total, double lo, double hi) {
    const Targets target = optimal_targets(weights, costs, total, lo, hi);
    std::vector<double> counts(weights.size());
    for_each_band(weights.size(), kBandPixels, [&](size_t, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) counts[i] = target(weights[i]);
    });
    return counts;
}

OptimalStrategy::Targets OptimalStrategy::optimal_targets(
    const std::vector<double>& weights, const std::vector<double>& costs, double total,
    double lo, double hi) {
    const size_t n = weights.size();
    Targets target;
    target.lo = lo;
    target.hi = hi;
    auto cost = [&](size_t i) { return costs.empty() ? 1.0 : costs[i]; };
    // Every sum here is summed in pixel order within bands of fixed size and the bands'
    // sums added in band order: the same bits with one thread or many.
    const size_t bands = band_count(n, kBandPixels);
    struct Totals {
        double floor = 0, cap = 0;  // every pixel at its floor, at its cap
        double weighted = 0;  // sum c_i w_i: a first guess, no pixel at floor or cap
        double rise = 0;      // what the pixels of positive weight add at their caps
    };
    std::vector<Totals> band_totals(bands);
    for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        Totals t;
        for (size_t i = begin; i < end; ++i) {
            t.floor += cost(i) * lo;
            t.cap += cost(i) * hi;
            if (weights[i] > 0) {
                t.weighted += cost(i) * weights[i];
                t.rise += cost(i) * (hi - lo);
            }
        }
        band_totals[band] = t;
    });
    Totals all;
    for (const Totals& t : band_totals) {
        all.floor += t.floor;
        all.cap += t.cap;
        all.weighted += t.weighted;
        all.rise += t.rise;
    }
    const double floor_cost = all.floor, cap_cost = all.cap;
    if (total <= floor_cost) {
        target.kind = Targets::kScaledFloors;
        target.factor = floor_cost > 0 ? total / floor_cost : 0.0;
        return target;
    }
    if (total >= cap_cost) {
        target.kind = Targets::kAllCapped;
        return target;
    }

    // f(mu) = sum_i c_i clamp(mu w_i, lo, hi) is continuous, piecewise linear and rising,
    // and on each piece it is C + S mu: C sums c_i lo over the pixels at their floor and
    // c_i hi over those at their cap, S sums c_i w_i over the others. Newton's step
    // from mu, (total - C) / S, is the root of mu's piece, so once it stays on its piece
    // it is the root. The steps are kept inside a bracket [below, above] with f(below)
    // < total <= f(above), bisecting (or doubling, while there is no upper end) when a
    // step would leave it, so the search ends on a piece whatever the weights; a few
    // passes over the weights at 1920x1080, where sorting the pieces' 2 n breakpoints,
    // or selecting among them, streamed 96 MB several times.
    std::vector<double> band_c(bands), band_s(bands);
    const auto piece = [&](double mu) {
        for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
            double c = 0, s = 0;
            for (size_t i = begin; i < end; ++i) {
                const double w = weights[i], x = w > 0 ? mu * w : lo;
                if (x <= lo)
                    c += cost(i) * lo;
                else if (x >= hi)
                    c += cost(i) * hi;
                else
                    s += cost(i) * w;
            }
            band_c[band] = c;
            band_s[band] = s;
        });
        double c = 0, s = 0;
        for (size_t b = 0; b < bands; ++b) {
            c += band_c[b];
            s += band_s[b];
        }
        return std::pair{c, s};
    };
    const double weighted = all.weighted;
    const double reach = floor_cost + all.rise;  // every pixel of positive weight capped
    double below = 0, above = std::numeric_limits<double>::infinity();
    double mu = weighted > 0 ? total / weighted : 1.0;
    // Pixels of weight 0 stay at their floor: a total they leave out of reach puts every
    // other pixel at its cap.
    if (total >= reach) mu = above;
    for (int step = 0; step < 4096 && mu < above; ++step) {
        const auto [c, s] = piece(mu);
        if (c + s * mu < total)
            below = mu;
        else
            above = mu;
        if (s > 0) {  // on a piece that rises: Newton's step
            const double next = (total - c) / s;
            if (next == mu) break;  // the root of its own piece
            if (next > below && next < above) {
                mu = next;
                continue;
            }
        }
        // Otherwise a step that narrows the bracket by orders of magnitude while its ends
        // are far apart (weights may span hundreds of them), by halves once they are
        // near.
        double middle;
        if (std::isinf(above))
            middle = below > 0 ? 16 * below : 1.0;
        else if (below == 0)
            middle = above / 16;
        else if (above > 4 * below)
            middle = std::sqrt(below) * std::sqrt(above);
        else
            middle = below + (above - below) / 2;
        if (!(middle > below && middle < above)) break;  // no double left between them
        mu = middle;
    }
    target.factor = mu;
    return target;
}

// Planning ahead. A round end holds up the farm: no job is out until the next round is
// planned, and planning a steered round passes over every pixel several times (~100 ms
// at 1920x1080). The last steered rounds are the shortest (each half of the one before),
// so that wait would be a large share of them. After a steered round that spends at most
// plan_ahead of the limit, the next is planned while that one is traced: from the
// buffers merged before it, with its own counts taken as had (samples, or its rays at
// each pixel's cost) and its fireflies answered a round later. next_round copies what
// the plan reads (read_merged, one pass) and leaves the rest to work the caller may run
// elsewhere. Which rounds are planned ahead and from what follows from the rounds alone,
// so the bytes of a render stay the same with the work done here or on another thread.
std::optional<Round> OptimalStrategy::next_round(const Accumulator& merged) {
    if (work_ahead_) std::exchange(work_ahead_, nullptr)();  // not taken: done here
    if (finished_) return std::nullopt;
    Round round{rounds_, {}};
    double share = 0;        // what a steered round spends of the limit
    bool read_here = false;  // planning_ holds what `merged` holds now
    if (!piloted_) {
        round.spp = pilot_round();
        // The first steered round end would take its ~150 MB of buffers (at 1920x1080)
        // from fresh pages, ~0.1 s of faults and zeroing while the farm waits: they are
        // taken while the pilot is traced instead.
        if (!finished_) work_ahead_ = [this] { prepare_buffers(); };
    } else {
        Steered steered;
        // Planned from older buffers but never made (its work was lost or threw):
        // planning it now from these would give other bytes than a render whose plan was
        // made.
        if (ahead_pending_ && !ahead_)
            throw std::logic_error("the round planned ahead was never made");
        if (ahead_) {
            steered = std::move(*ahead_);
            ahead_.reset();
            ahead_pending_ = false;
        } else {
            read_merged(merged, cost_aware_, {}, planning_);
            read_here = true;
            // A budget given in samples is, in rays, what those samples cost at the
            // pilot's mean.
            if (cost_aware_ && ray_budget_ == 0)
                ray_budget_ = double(budget_) * planning_.mean_cost;
            steered = steered_round();
        }
        if (steered.spp.empty()) {
            finished_ = true;
            return std::nullopt;
        }
        round.spp = std::move(steered.spp);
        share = steered.share;
        out_spends_rest_ = steered.spends_rest;
    }
    const uint64_t total = round.total();
    if (total == 0) {
        finished_ = true;
        return std::nullopt;
    }
    issued_ += total;
    ++rounds_;
    // The pilot's second half (round 1 of a split pilot): the first plan is made ahead.
    const bool pilot_half = split_pilot_ && round.index == 1;
    if (pilot_half || (share > 0 && share <= plan_ahead_ * limit())) {
        // A round planned here leaves in planning_ what the next plan would read again
        // (its only change, non-finite variances made the largest, is one the next plan
        // makes too): the round out is all that plan lacks. ~10 ms of this round end at
        // 1920x1080, the last planned in place.
        if (read_here)
            planning_.in_flight = round.spp;
        else
            read_merged(merged, cost_aware_, round.spp, planning_);
        // The first plan, made ahead: the ray budget from the pilot's first half.
        if (cost_aware_ && ray_budget_ == 0)
            ray_budget_ = double(budget_) * planning_.mean_cost;
        ahead_pending_ = true;
        work_ahead_ = [this] { ahead_ = steered_round(); };
    }
    return round;
}

void OptimalStrategy::prepare_buffers() {
    const size_t pixels = size_t(width_) * height_;
    Planning& b = planning_;
    b.variance.resize(pixels);
    b.cost.resize(cost_aware_ ? pixels : 0);
    b.samples.resize(pixels);
    b.sigma.resize(pixels);
    b.room.resize(pixels);
    // The remainder's keys are sorted only when a pixel's cost is not 1 or a cap binds
    // (apportion): optimal's round ends leave them untouched, 32 MB at 1920x1080.
    if (cost_aware_) b.apportion.keys.resize(pixels);
    prepared_ = true;
}

std::function<void()> OptimalStrategy::take_work_ahead() {
    return std::exchange(work_ahead_, nullptr);
}

std::vector<uint32_t> OptimalStrategy::pilot_round() {
    piloted_ = true;
    const size_t pixels = size_t(width_) * height_;
    const uint64_t pilot = pilot_spp_;
    if (split_pilot_) {
        const uint64_t first = pilot / 2;
        Steered second;
        second.spp.assign(pixels, uint32_t(pilot - first));
        ahead_ = std::move(second);
        ahead_pending_ = true;
        return std::vector<uint32_t>(pixels, uint32_t(first));
    }
    if (pilot > 0) return std::vector<uint32_t>(pixels, uint32_t(pilot));
    // Less than a sample per pixel: nothing can be estimated, so the budget is spread
    // evenly (hash-ordered, not the first rows) in one round.
    finished_ = true;
    return apportion(std::vector<double>(pixels, 1.0), double(budget_),
                     std::vector<uint32_t>(pixels, cap_));
}

OptimalStrategy::Steered OptimalStrategy::steered_round() {
    Planning& b = planning_;
    const size_t pixels = size_t(width_) * height_;
    std::vector<double>& cost = b.cost;  // empty for optimal: every sample costs 1
    // A round planned ahead counts the round out as spent: its samples, or their rays at
    // each pixel's cost.
    double spent = b.spent;
    if (!b.in_flight.empty()) {
        std::vector<double> band_sums(band_count(pixels, kBandPixels), 0.0);
        for_each_band(pixels, kBandPixels, [&](size_t band, size_t begin, size_t end) {
            double sum = 0;
            for (size_t i = begin; i < end; ++i)
                sum += double(b.in_flight[i]) * (cost_aware_ ? cost[i] : 1.0);
            band_sums[band] = sum;
        });
        for (double sum : band_sums) spent += sum;
    }
    const double remaining = limit() - spent;
    if (!(remaining >= 1)) return {};
    // optimal-time's rays are predicted from each pixel's cost so far, and a round costs
    // more or less than predicted (Russian roulette): after a round that spends all that
    // was left, the difference is left alone (the budget is met to within that noise,
    // docs/STRATEGIES.md), not chased by rounds of a few samples, each behind a whole
    // round end. optimal's samples are exact: what a cap kept a round from placing is
    // tried again.
    if (cost_aware_ && out_spends_rest_) return {};
    // Each round spends at most as much as all before it (at most what is left), so the
    // estimates that steer a round rest on at least half of the render so far. With
    // steer_rounds k, a round also spends at most half of what is left, and the k-th
    // after the pilot all of it: sigma is re-estimated from every merged sample before
    // each, so a firefly drawn in one round is answered in the next (as Cycles answers it
    // at its next check), and the last rounds, whose fireflies are never answered, are
    // the small ones.
    double share = std::min(remaining, std::max(spent, 1.0));
    if (steer_rounds_ > 0) {
        // The pilot is round 0 (and 1, when split).
        const uint32_t pilot_rounds = split_pilot_ ? 2 : 1;
        const uint32_t steered = rounds_ > pilot_rounds ? rounds_ - pilot_rounds : 0;
        share = steered + 1 < steer_rounds_
                    ? std::min(share, std::max(1.0, std::floor(remaining / 2)))
                    : remaining;
    }

    estimate_sigma(b, width_, height_, sigma_radius_, sigma_prior_, sigma_self_out_);
    if (!prepared_) prepare_buffers();
    // sigma becomes each pixel's weight in place: w_i = r_i^(2/3) = cbrt(r_i^2), r_i =
    // sigma_i (optimal-time: sigma_i / c_i). The squares of a chunk are taken first, so
    // that the loops over it, without branches, are the ones the compiler vectorises
    // (cube_root.h) and write over the sigma they were taken from.
    std::vector<double>& weight = b.sigma;
    std::vector<char> band_any(band_count(pixels, kBandPixels), 0);
    for_each_band(pixels, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        constexpr size_t kChunk = 512;
        double square[kChunk];
        long any = 0;
        for (size_t first = begin; first < end; first += kChunk) {
            const size_t m = std::min(kChunk, end - first);
            double* const w = weight.data() + first;
            if (cost_aware_)
                for (size_t j = 0; j < m; ++j)
                    square[j] = (w[j] / cost[first + j]) * (w[j] / cost[first + j]);
            else
                for (size_t j = 0; j < m; ++j) square[j] = w[j] * w[j];
            for (size_t j = 0; j < m; ++j) w[j] = inverse_cube_root_guess(square[j]);
            for (size_t j = 0; j < m; ++j) w[j] = cube_root_from_guess(square[j], w[j]);
            long odd = 0;
            for (size_t j = 0; j < m; ++j) odd |= long(!cube_root_steps_hold(square[j]));
            if (odd)  // 0, a subnormal, infinity or NaN
                for (size_t j = 0; j < m; ++j)
                    if (!cube_root_steps_hold(square[j])) w[j] = std::cbrt(square[j]);
            for (size_t j = 0; j < m; ++j) any |= long(w[j] > 0);
        }
        band_any[band] = char(any);
    });
    const bool noise_seen =
        std::find(band_any.begin(), band_any.end(), 1) != band_any.end();
    // With no noise seen anywhere every pixel weighs the same.
    if (!noise_seen) std::fill(weight.begin(), weight.end(), 1.0);

    // The round closes the gap between each pixel's target and what it has; pixels
    // already past their target get nothing, so the gaps are scaled to the share. The
    // targets are not kept: each is the gap's, in place of the weight it follows from.
    const Targets target =
        optimal_targets(weight, cost, spent + share, double(min_spp_), double(cap_));
    std::vector<double>& gap = weight;
    // The same pass sums what apportion scales the gaps by (its kept_total).
    std::vector<uint32_t>& room = b.room;
    room.resize(pixels);
    std::vector<double> band_kept(band_count(pixels, kBandPixels), 0.0);
    for_each_band(pixels, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        double kept = 0;
        for (size_t i = begin; i < end; ++i) {
            const uint64_t have =
                b.samples[i] + (b.in_flight.empty() ? 0 : b.in_flight[i]);
            gap[i] = std::max(0.0, target(weight[i]) - double(have));
            room[i] = have < cap_ ? uint32_t(cap_ - have) : 0;
            if (gap[i] > 0 && room[i] > 0) kept += (cost_aware_ ? cost[i] : 1.0) * gap[i];
        }
        band_kept[band] = kept;
    });
    double kept_total = 0;
    for (double kept : band_kept) kept_total += kept;
    return {apportion(gap, share, room, cost, &b.apportion, &kept_total), share,
            share >= remaining};
}

void OptimalStrategy::restore_planned_round(std::vector<uint32_t> spp) {
    // None given where the state holds one: next_round finds it never made.
    if (spp.empty()) return;
    if (!restored_ahead_)
        throw std::runtime_error(name() +
                                 ": a round planned ahead that its state does not hold");
    const size_t pixels = size_t(width_) * height_;
    if (spp.size() != pixels ||
        std::any_of(spp.begin(), spp.end(), [&](uint32_t s) { return s > cap_; }))
        throw std::runtime_error(name() +
                                 ": the round planned ahead does not fit the render");
    Steered round = std::move(*restored_ahead_);
    restored_ahead_.reset();
    round.spp = std::move(spp);
    ahead_ = std::move(round);
}

nlohmann::json OptimalStrategy::outcome() const {
    nlohmann::json out = {{"budget", budget_}, {"samples", issued_}, {"rounds", rounds_}};
    if (cost_aware_)
        out["ray_budget"] = ray_budget_;
    else
        out["unspent"] = budget_ > issued_ ? budget_ - issued_ : 0;
    return out;
}

nlohmann::json OptimalStrategy::save_state() const {
    nlohmann::json state = {
        {"ray_budget", ray_budget_}, {"rounds", rounds_},
        {"issued", issued_},         {"piloted", piloted_},
        {"finished", finished_},     {"spends_rest", out_spends_rest_}};
    // A round planned ahead and made: what it spends; its counts are the checkpoint's
    // (round_planned_ahead), too large for this state.
    if (ahead_pending_ && ahead_)
        state["ahead"] = {{"share", ahead_->share}, {"spends_rest", ahead_->spends_rest}};
    return state;
}

void OptimalStrategy::restore_state(const nlohmann::json& state) {
    ray_budget_ = state.at("ray_budget").get<double>();
    rounds_ = state.at("rounds").get<uint32_t>();
    issued_ = state.at("issued").get<uint64_t>();
    piloted_ = state.at("piloted").get<bool>();
    finished_ = state.at("finished").get<bool>();
    work_ahead_ = nullptr;
    ahead_.reset();
    // Saved while a round planned ahead was held: it is pending until its counts come
    // back (restore_planned_round); a next_round without them is an error, not a plan
    // from other buffers.
    ahead_pending_ = state.contains("ahead");
    restored_ahead_.reset();
    if (ahead_pending_) {
        const nlohmann::json& a = state.at("ahead");
        Steered meta;
        meta.share = a.at("share").get<double>();
        meta.spends_rest = a.at("spends_rest").get<bool>();
        restored_ahead_ = std::move(meta);
    }
    // States saved before it existed: a round end that follows the last round then
    // plans the rest of optimal-time's rays, as it did.
    out_spends_rest_ = state.value("spends_rest", false);
}

}  // namespace aliquot
