// OptimalStrategy: our method. Progressive rounds that give pixel i a share of the budget
// proportional to sigma_i^(2/3), the allocation that minimises the expected mean absolute
// error; `optimal-time` weighs by (sigma_i / c_i)^(2/3) with c_i the pixel's rays per
// sample, minimising the error for a fixed time (rays) instead of a fixed sample count.
#pragma once

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
    nlohmann::json outcome() const override;

    // optimal-time's budget in rays (budget * the pilot's mean rays per sample); 0 before
    // the pilot is merged.
    double ray_budget() const { return ray_budget_; }

    // Per-pixel standard deviation of one sample's luminance, protected against estimates
    // that are too low at low sample counts (see the .cpp); with `radius` > 0, pooled
    // over the (2 radius + 1)^2 pixels around each (sigma_radius); with `prior` > 0,
    // shrunk towards that pool as a prior worth `prior` samples (sigma_prior).
    static std::vector<double> sigma_estimates(const Accumulator& merged,
                                               uint32_t radius = 0, uint32_t prior = 0);

    // The real-valued optimum n_i = clamp(lambda * w_i, lo, hi) with sum_i c_i n_i =
    // total (c_i = costs[i], or 1 when costs is empty). Below the floor's cost the floors
    // are scaled down; above the caps' cost every pixel is at its cap.
    static std::vector<double> optimal_counts(const std::vector<double>& weights,
                                              const std::vector<double>& costs,
                                              double total, double lo, double hi);

private:
    // As above, into `sigma`, with `variance` to work in; with `costs`, each pixel's
    // measured rays per sample too (the mean for a pixel not yet sampled), made in the
    // same pass.
    static void sigma_estimates(const Accumulator& merged, uint32_t radius,
                                uint32_t prior, std::vector<double>& variance,
                                std::vector<double>* costs, std::vector<double>& sigma);
    // As above, into `counts`.
    static void optimal_counts(const std::vector<double>& weights,
                               const std::vector<double>& costs, double total, double lo,
                               double hi, std::vector<double>& counts);

    // The first round: min_spp everywhere, the estimates' foundation.
    std::vector<uint32_t> pilot_round();
    // A later round from the merged estimates; nullopt when the budget is spent.
    std::optional<std::vector<uint32_t>> steered_round(const Accumulator& merged);

    uint32_t width_, height_;
    uint64_t budget_;
    uint32_t min_spp_, cap_, sigma_radius_, sigma_prior_, steer_rounds_;
    bool cost_aware_;

    double ray_budget_ = 0;
    uint32_t rounds_ = 0;
    uint64_t issued_ = 0;  // samples handed out in all rounds
    bool piloted_ = false;
    bool finished_ = false;

    // Each pixel's weight as the last round end computed it, with the sigma (and cost) it
    // was computed from: a weight is a function of those alone, so where they have not
    // changed (most pixels of a late steered round, which gives samples to few) the
    // `cbrt` is not taken again. The same bits as computing every weight; nothing of it
    // is saved with the render.
    std::vector<double> weight_sigma_, weight_cost_, weight_;

    // The buffers a round end plans in, kept for the next: at 1920x1080 each is 8-32 MB,
    // and taking them fresh every round end cost the kernel's page faults and zeroing
    // (~25 ms of optimal-time's). Each round end writes every element before reading it,
    // so nothing carries from one round to the next; nothing of it is saved.
    struct Planning {
        std::vector<double> variance, sigma, cost, gap;
        std::vector<uint32_t> room;
        ApportionScratch apportion;
    };
    Planning planning_;
};

}  // namespace aliquot
