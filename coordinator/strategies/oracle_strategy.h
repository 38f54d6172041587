// OracleStrategy: the limit of allocation. Given each pixel's true per-sample standard
// deviation (from a separate high-spp render, never one sharing the judged render's
// seed), it spends the budget as n_i = clamp(mu sigma_i^(2/3), min_spp, max_spp), the
// allocation `optimal` estimates as it goes; no pilot, no estimation error.
#pragma once

#include <memory>
#include <vector>

#include "strategy.h"
#include "strategy_params.h"

namespace aliquot {

class OracleStrategy : public Strategy {
public:
    // Uses params.true_sigma (one value per pixel, validated), budget (or spp), min_spp
    // and max_spp.
    OracleStrategy(const StrategyParams& params, uint32_t width, uint32_t height);

    std::string name() const override { return "oracle"; }
    std::optional<Round> next_round(const Accumulator& merged) override;
    uint64_t planned_samples() const override { return planned_; }
    nlohmann::json save_state() const override;
    void restore_state(const nlohmann::json& state) override;
    nlohmann::json outcome() const override;

    // Whole per-pixel counts of the whole render, decided up front from sigma alone.
    const std::vector<uint32_t>& allocation() const { return allocation_; }

private:
    std::vector<uint32_t> allocation_;
    uint64_t budget_ = 0, planned_ = 0;
    uint32_t rounds_total_ = 1, rounds_ = 0;
};

}  // namespace aliquot
