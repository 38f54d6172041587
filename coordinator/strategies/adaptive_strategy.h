// AdaptiveStrategy: the seed's a-sampling. A uniform initial pass, then the rest of the
// budget split over square buckets by their variance (max - min pixel value), min(v / V,
// 1)^alpha.
#pragma once

#include "strategy.h"
#include "strategy_params.h"

namespace aliquot {

class AdaptiveStrategy : public Strategy {
public:
    // Uses budget (or spp), initial_spp, max_variance, alpha, bucket_size and max_spp.
    AdaptiveStrategy(const StrategyParams& params, uint32_t width, uint32_t height);

    std::string name() const override { return "adaptive"; }
    std::optional<Round> next_round(const Accumulator& merged) override;
    uint64_t planned_samples() const override { return budget_; }
    nlohmann::json save_state() const override;
    void restore_state(const nlohmann::json& state) override;
    std::vector<Bucket> buckets() const override;
    nlohmann::json outcome() const override;

    // A delivery after the decision depends on nothing merged, so each hands the farm the
    // next as work ahead, as uniform's rounds do: its jobs are leased while the delivery
    // out's last jobs are traced, and no delivery's end is waited through (docs/FARM.md,
    // "Two rounds out"). The state (delivered_) says which delivery it is, so it is not
    // a planned round to checkpoint.
    std::function<void()> take_work_ahead() override;
    const std::vector<uint32_t>* round_planned_ahead() const override {
        return ahead_.empty() ? nullptr : &ahead_;
    }

    uint32_t initial_spp() const { return initial_spp_; }  // after fitting the budget

    // The seed's bucket "variance": the largest minus the smallest pixel value in the
    // bucket, where a pixel's value is the luminance of its mean (one number for an RGB
    // pixel).
    static double bucket_variance(const Accumulator& merged, const PixelRect& rect);
    // min(v / max_variance, 1)^alpha per bucket, scaled so the largest is 1. Computed
    // from logarithms, so tiny ratios and large alphas keep their proportions instead of
    // all underflowing to 0. alpha = 0 weighs every bucket alike (0^0 = 1).
    static std::vector<double> bucket_weights(const std::vector<double>& variances,
                                              double max_variance, double alpha);

private:
    enum class Phase { initial, allocate, deliver, done };
    std::vector<PixelRect> grid() const;
    void plan_remainder();
    // Delivery r of deliveries_: each pixel's share of extra_.
    void deliver(uint64_t r, std::vector<uint32_t>& spp) const;

    uint32_t width_, height_;
    uint64_t budget_;
    uint32_t initial_spp_, bucket_size_, cap_;
    double max_variance_, alpha_;

    Phase phase_ = Phase::initial;
    std::vector<double> variances_, weights_;  // per bucket, from the initial pass
    uint64_t remainder_ = 0, unspent_ = 0;
    uint32_t deliveries_ = 0, delivered_ = 0, rounds_ = 0;
    std::vector<uint32_t> extra_;       // per pixel, derived from weights_ (not saved)
    std::function<void()> work_ahead_;  // fills ahead_ with the next delivery
    std::vector<uint32_t> ahead_;       // the delivery after the one out, once made
};

}  // namespace aliquot
