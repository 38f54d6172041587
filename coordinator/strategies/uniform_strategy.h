// UniformStrategy: every pixel gets the same number of samples (the seed's floor(B/N)),
// delivered in progressive rounds so that progress and error can be watched as it
// converges.
#pragma once

#include "strategy.h"

namespace aliquot {

class UniformStrategy : public Strategy {
public:
    UniformStrategy(uint32_t width, uint32_t height, uint32_t spp);

    std::string name() const override { return "uniform"; }
    std::optional<Round> next_round(const Accumulator& merged) override;
    uint64_t planned_samples() const override { return uint64_t(spp_) * pixels_; }
    nlohmann::json save_state() const override;
    void restore_state(const nlohmann::json& state) override;

    // The next round's counts never depend on the results, so each round hands the farm
    // the one after it as work ahead: its jobs are leased while the round out's last job
    // is traced, and no round end is waited through (docs/FARM.md, "Two rounds out"). The
    // state alone says what that round is, so it is not a planned round to checkpoint.
    std::function<void()> take_work_ahead() override;
    const std::vector<uint32_t>* round_planned_ahead() const override {
        return ahead_.empty() ? nullptr : &ahead_;
    }

    // How much the render's samples so far grow a round after the first.
    static constexpr uint32_t kRoundGrowth = 8;
    // Samples per pixel of the next round after `done` of `spp`: a first round of about
    // kFirstRoundSamples, then rounds of (kRoundGrowth - 1) x done, up to about
    // round_samples(spp x pixels) samples.
    static uint32_t round_spp(uint32_t done, uint32_t spp, size_t pixels);

private:
    uint32_t spp_;
    size_t pixels_;
    uint32_t done_ = 0;
    uint32_t rounds_ = 0;
    std::function<void()> work_ahead_;  // fills ahead_ with the next round's counts
    std::vector<uint32_t> ahead_;       // the round after the one out, once made
};

}  // namespace aliquot
