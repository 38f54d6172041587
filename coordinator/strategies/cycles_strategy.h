// CyclesStrategy: Blender Cycles' adaptive sampling, re-implemented from its manual and
// public descriptions (docs/STRATEGIES.md names them) so our methods can be compared
// with what a production renderer ships. Every pixel gets the minimum samples; then,
// every `adaptive_step` samples, a pixel whose error from two half-sample images is
// below the noise threshold stops, unless a neighbour is still above it.
#pragma once

#include <vector>

#include "strategy.h"
#include "strategy_params.h"

namespace aliquot {

class CyclesStrategy : public Strategy {
public:
    // Uses noise_threshold, adaptive_min_samples, adaptive_step, max_spp (0: Cycles'
    // default of 4096 samples) and, as a cap on the total, budget or spp or max_samples.
    CyclesStrategy(const StrategyParams& params, uint32_t width, uint32_t height);

    std::string name() const override { return "cycles"; }
    std::optional<Round> next_round(const Accumulator& merged) override;
    uint64_t planned_samples() const override;
    nlohmann::json save_state() const override;
    void restore_state(const nlohmann::json& state) override;
    nlohmann::json outcome() const override;

    // Cycles' automatic minimum: 16 / threshold^0.3 (threshold 0.1 -> 32, 0.01 -> 64,
    // 0.001 -> 128), at least 4.
    static uint32_t automatic_min_samples(double threshold);
    // A pixel's error as Cycles measures it: sum over RGB of |full mean - half mean|,
    // over the square root of the full mean's RGB sum (noise relative to the eye's
    // sensitivity to brightness). Infinite below two samples: never converged.
    static double pixel_error(const Accumulator& merged, size_t i);
    // Converged pixels with an unconverged pixel among their eight neighbours are made
    // unconverged: a row pass, then a column pass (a 3x3 dilation of the unconverged).
    static std::vector<bool> dilate_unconverged(const std::vector<bool>& converged,
                                                uint32_t width, uint32_t height);

    uint32_t min_samples() const { return min_samples_; }

private:
    // The dilation in two passes: a row's pixels converged with both neighbours in the
    // row, then pixel (x, y) of those with both neighbours in its column.
    static void dilate_row(const char* below, char* rows, uint32_t width);
    static bool dilated(const std::vector<char>& rows, uint32_t x, uint32_t y,
                        uint32_t width, uint32_t height);
    // Brings below_ and rows_ up to date with `merged`.
    void judge(const Accumulator& merged);

    uint32_t width_, height_;
    double threshold_;
    uint32_t min_samples_, step_, max_spp_;
    uint64_t max_samples_;

    uint32_t rounds_ = 0;
    double converged_fraction_ = 0;
    std::string stopped_by_;  // empty while running

    // Kept from one round end to the next (nothing of it is saved): a pixel's error is a
    // function of its own sums, which change only when it gets samples, so a pixel is
    // judged again only when its sample count differs from the one it was judged at.
    // Late in a render most pixels have stopped, and judging every pixel every round
    // (divisions and a square root each) was most of a round end. below_: the error is
    // under the threshold; judged_at_: the samples then (kNeverJudged: not yet, or more
    // than fit); rows_: the dilation's row pass.
    std::vector<char> below_, rows_;
    std::vector<uint32_t> judged_at_;
};

}  // namespace aliquot
