// OptimalStrategy: our method. Progressive rounds that give pixel i a share of the budget
// proportional to sigma_i^(2/3), the allocation that minimises the expected mean absolute
// error; `optimal-time` weighs by (sigma_i / c_i)^(2/3) with c_i the pixel's rays per
// sample, minimising the error for a fixed time (rays) instead of a fixed sample count.
#pragma once

#include <algorithm>
#include <functional>
#include <optional>

#include "allocation.h"
#include "strategy.h"
#include "strategy_params.h"

namespace aliquot {

class OptimalStrategy : public Strategy {
public:
    // Uses budget (or spp), min_spp and max_spp.
    OptimalStrategy(const StrategyParams& params, uint32_t width, uint32_t height,
                    bool cost_aware);

    std::string name() const override { return cost_aware_ ? "optimal-time" : "optimal"; }
    std::optional<Round> next_round(const Accumulator& merged) override;
    uint64_t planned_samples() const override { return budget_; }
    nlohmann::json save_state() const override;
    void restore_state(const nlohmann::json& state) override;
    void restore_planned_round(std::vector<uint32_t> spp) override;
    nlohmann::json outcome() const override;

    // optimal-time's budget in rays (budget * the pilot's mean rays per sample); 0 before
    // the pilot is merged.
    double ray_budget() const { return ray_budget_; }

    // Per-pixel standard deviation of one sample's luminance, protected against estimates
    // that are too low at low sample counts (see the .cpp); with `radius` > 0, pooled
    // over the (2 radius + 1)^2 pixels around each (sigma_radius); with `prior` > 0,
    // shrunk towards that pool as a prior worth `prior` samples (sigma_prior); with
    // `self_out` > 0, the mean over the (2 self_out + 1)^2 - 1 pixels around each, its
    // own left out (sigma_self_out), in place of both.
    static std::vector<double> sigma_estimates(const Accumulator& merged,
                                               uint32_t radius = 0, uint32_t prior = 0,
                                               uint32_t self_out = 0);

    // The real-valued optimum n_i = clamp(lambda * w_i, lo, hi) with sum_i c_i n_i =
    // total (c_i = costs[i], or 1 when costs is empty). Below the floor's cost the floors
    // are scaled down; above the caps' cost every pixel is at its cap.
    static std::vector<double> optimal_counts(const std::vector<double>& weights,
                                              const std::vector<double>& costs,
                                              double total, double lo, double hi);

    std::function<void()> take_work_ahead() override;
    bool holds_planned_round() const override { return ahead_pending_; }
    const std::vector<uint32_t>* round_planned_ahead() const override {
        return ahead_ && !ahead_->spp.empty() ? &ahead_->spp : nullptr;
    }

private:
    // The buffers a round end plans in, kept for the next: at 1920x1080 each is 8-32 MB,
    // and taking them fresh every round end cost the kernel's page faults and zeroing
    // (~25 ms of optimal-time's). Every element is written before it is read, so nothing
    // carries from one plan to the next; nothing of it is saved.
    struct Planning {
        // What a plan reads of the merged buffers, copied by read_merged at a round
        // boundary: each pixel's luminance variance, samples and (optimal-time) rays per
        // sample, the round out meanwhile when the plan is made ahead (else empty), and
        // the totals.
        std::vector<double> variance, cost;
        std::vector<uint64_t> samples;
        std::vector<uint32_t> in_flight;
        double largest = 0;      // the largest finite variance
        bool nonfinite = false;  // some variance is not finite (an overflowed sum)
        double spent = 0;        // samples (optimal-time: rays) merged
        double mean_cost = 1;    // rays per sample merged
        // Worked in by the plan. Each pixel's sigma, then in place its weight (sigma_i /
        // c_i)^(2/3), then the gap between its target and what it has: one buffer that
        // each pass reads and writes pixel by pixel, 16 MB at 1920x1080 where three were
        // 48 MB of pages to fault in and stream.
        std::vector<double> sigma;
        std::vector<uint32_t> room;
        ApportionScratch apportion;
        // The image median's per-band histograms and the values of its bucket (8 MB of
        // fresh pages a plan at 1920x1080 when taken anew).
        std::vector<std::vector<uint32_t>> median_counts;
        std::vector<double> median_candidates;
    };
    // A steered round's counts and what it spends of the limit; no counts: the budget is
    // spent.
    struct Steered {
        std::vector<uint32_t> spp;
        double share = 0;
        bool spends_rest = false;  // share is all that was left
    };

    // Copies what a plan reads of `merged` into `b`, with `in_flight` (a round out, or
    // empty); costs only when `costs`.
    static void read_merged(const Accumulator& merged, bool costs,
                            const std::vector<uint32_t>& in_flight, Planning& b);
    // b.sigma from b.variance (and b.samples, for the prior); see sigma_estimates.
    static void estimate_sigma(Planning& b, uint32_t width, uint32_t height,
                               uint32_t radius, uint32_t prior, uint32_t self_out);
    // What optimal_counts finds: each pixel's target as a function of its weight alone.
    struct Targets {
        enum { kScaledFloors, kAllCapped, kClamped } kind = kClamped;
        double factor = 1;  // the floors' scale, or the multiplier mu
        double lo = 0, hi = 0;
        double operator()(double w) const {
            switch (kind) {
                case kScaledFloors:
                    return lo * factor;
                case kAllCapped:
                    return hi;
                default:
                    return w > 0 ? std::clamp(factor * w, lo, hi) : lo;
            }
        }
    };
    static Targets optimal_targets(const std::vector<double>& weights,
                                   const std::vector<double>& costs, double total,
                                   double lo, double hi);

    // Sizes (and so touches) the planning buffers.
    void prepare_buffers();
    // The first round: min_spp everywhere, the estimates' foundation; its first half
    // when the pilot is split (split_pilot_), the second then held in ahead_.
    std::vector<uint32_t> pilot_round();
    // A later round from what read_merged copied into planning_.
    Steered steered_round();
    // The budget in the unit steered rounds spend: samples, or optimal-time's rays.
    double limit() const { return cost_aware_ ? ray_budget_ : double(budget_); }

    uint32_t width_, height_;
    uint64_t budget_;
    uint32_t min_spp_, cap_, sigma_radius_, sigma_prior_, sigma_self_out_, steer_rounds_;
    double plan_ahead_;
    bool cost_aware_;
    // The pilot's samples a pixel, and whether it is traced in two rounds of half each so
    // that the first steered round is planned, from the first half, while the second is
    // traced: when the pilot's share of the budget is at most plan_ahead (docs/
    // STRATEGIES.md, "Planning ahead"). Both follow from the parameters alone.
    uint64_t pilot_spp_;
    bool split_pilot_;

    double ray_budget_ = 0;
    uint32_t rounds_ = 0;
    uint64_t issued_ = 0;  // samples handed out in all rounds
    bool piloted_ = false;
    bool finished_ = false;

    Planning planning_;
    bool prepared_ = false;  // planning_'s buffers are sized

    // Planning ahead (docs/STRATEGIES.md): the plan of the next round, to be made by
    // work_ahead_ (or by whoever took it) and then kept in ahead_ until next_round hands
    // it out; ahead_pending_ from the moment it is arranged until then. After the pilot,
    // work_ahead_ only prepares the buffers.
    std::function<void()> work_ahead_;
    std::optional<Steered> ahead_;
    bool ahead_pending_ = false;
    bool out_spends_rest_ = false;  // the last round handed out spends all that was left
    // What a restored state says of its round planned ahead, until its counts come back.
    std::optional<Steered> restored_ahead_;
};

}  // namespace aliquot
