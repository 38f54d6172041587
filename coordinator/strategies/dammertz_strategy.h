// DammertzStrategy: the seed's d-sampling, after Dammertz, Hanika, Keller and Lensch, "A
// Hierarchical Automatic Stopping Condition for Monte Carlo Global Illumination" (WSCG
// 2009). A tree of buckets that are sampled until the error between their even-sample and
// odd-sample images is at most V, split where that error is halved, and stopped by caps
// otherwise.
#pragma once

#include "strategy.h"
#include "strategy_params.h"

namespace aliquot {

class DammertzStrategy : public Strategy {
public:
    enum class State { active, converged, capped };  // capped: stopped at max_spp
    struct Leaf {
        PixelRect rect;
        State state = State::active;
        double error = 0;  // E at the last evaluation
    };

    // Uses max_variance, samples_per_iteration, split_factor, min_bucket_size, error_norm
    // and the caps max_spp (0: 65536) and max_samples (0: 4096 per pixel; budget, or spp
    // * pixels, caps it too when given).
    DammertzStrategy(const StrategyParams& params, uint32_t width, uint32_t height);

    std::string name() const override { return "dammertz"; }
    std::optional<Round> next_round(const Accumulator& merged) override;
    uint64_t planned_samples() const override;
    nlohmann::json save_state() const override;
    void restore_state(const nlohmann::json& state) override;
    std::vector<Bucket> buckets() const override;
    nlohmann::json outcome() const override;

    const std::vector<Leaf>& leaves() const { return leaves_; }
    uint32_t max_spp() const { return max_spp_; }
    uint64_t max_samples() const { return max_samples_; }

    // Per-pixel error of `rect` (row-major) under the configured norm, and the bucket's
    // E.
    std::vector<double> pixel_errors(const Accumulator& merged,
                                     const PixelRect& rect) const;
    double bucket_error(const std::vector<double>& pixel_errors) const;

    // Cuts `rect` perpendicular to its longer axis where the error in `pixel_errors` is
    // halved, keeping both sides at least `min_size`; nullopt when it is too small.
    static std::optional<std::pair<PixelRect, PixelRect>> split(
        const PixelRect& rect, const std::vector<double>& pixel_errors,
        uint32_t min_size);

private:
    // A leaf after its evaluation: itself (judged, or left as it was), or its two halves.
    struct Judged {
        Leaf first;
        std::optional<Leaf> second;
    };
    Judged judge(const Accumulator& merged, Leaf leaf) const;
    void evaluate(const Accumulator& merged);
    // One pixel's error under the configured norm (pixel_errors' value for it), and the
    // sum of `rect`'s in pixel_errors' row-major order, without keeping them.
    double pixel_error(const Accumulator& merged, size_t i) const;
    double error_sum(const Accumulator& merged, const PixelRect& rect) const;
    // E from the sum of `pixels` pixel errors (bucket_error's arithmetic), and of `part`
    // of `rect` from rect's pixel errors.
    double bucket_error(double sum, size_t pixels) const;
    double part_error(const std::vector<double>& errors, const PixelRect& rect,
                      const PixelRect& part) const;
    std::string stop_reason() const;

    uint32_t width_, height_;
    double max_variance_;
    uint32_t samples_per_iteration_;
    double split_factor_;
    uint32_t min_bucket_size_;
    bool paper_norm_;
    uint32_t max_spp_;
    uint64_t max_samples_;

    std::vector<Leaf> leaves_;
    uint32_t rounds_ = 0;
    bool evaluate_pending_ =
        false;  // a round was issued and its leaves are not judged yet
    bool finished_ = false;
    bool stopped_by_max_samples_ = false;
};

}  // namespace aliquot
