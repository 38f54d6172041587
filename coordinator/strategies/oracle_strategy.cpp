#include "oracle_strategy.h"

#include <algorithm>
#include <cmath>

#include "allocation.h"
#include "optimal_strategy.h"

namespace aliquot {

OracleStrategy::OracleStrategy(const StrategyParams& p, uint32_t width, uint32_t height) {
    const size_t pixels = size_t(width) * height;
    budget_ = sample_budget(p, pixels);
    const uint32_t cap = spp_cap(p);
    const std::vector<float>& sigma = *p.true_sigma;  // validate() checked its size
    std::vector<double> weight(pixels);
    bool any = false;
    for (size_t i = 0; i < pixels; ++i) {
        weight[i] = std::cbrt(double(sigma[i]) * double(sigma[i]));
        any = any || weight[i] > 0;
    }
    if (!any) std::fill(weight.begin(), weight.end(), 1.0);  // a noiseless image
    // The same solver and floor as `optimal`, so the two differ only in where sigma comes
    // from. Pixels of sigma 0 still get the floor: one sample is needed to know their
    // value.
    const double floor = std::min<double>(p.min_spp, double(budget_) / double(pixels));
    const std::vector<double> target =
        OptimalStrategy::optimal_counts(weight, {}, double(budget_), floor, double(cap));
    allocation_ = apportion(target, double(budget_), std::vector<uint32_t>(pixels, cap));
    for (uint32_t n : allocation_) planned_ += n;
    // Rounds of about round_samples(budget) (an eighth of the budget, at least
    // kRoundSamples): the allocation is fixed, so rounds only let progress and the
    // per-round error be watched and keep checkpoints frequent, and each merges every
    // pixel once more.
    const uint64_t round = round_samples(budget_);
    rounds_total_ = uint32_t(std::max<uint64_t>(1, (planned_ + round - 1) / round));
}

std::optional<Round> OracleStrategy::next_round(const Accumulator&) {
    while (rounds_ < rounds_total_) {
        // Round r of K gives floor(a (r+1) / K) - floor(a r / K): whole, and adding up to
        // a over the K rounds.
        const uint64_t r = rounds_, k = rounds_total_;
        Round round{rounds_, std::vector<uint32_t>(allocation_.size())};
        for (size_t i = 0; i < allocation_.size(); ++i) {
            const uint64_t a = allocation_[i];
            round.spp[i] = uint32_t(a * (r + 1) / k - a * r / k);
        }
        ++rounds_;
        if (round.total() > 0) return round;
    }
    return std::nullopt;
}

nlohmann::json OracleStrategy::outcome() const {
    return {{"budget", budget_},
            {"samples", planned_},
            {"unspent", budget_ > planned_ ? budget_ - planned_ : 0}};
}

nlohmann::json OracleStrategy::save_state() const {
    return {{"rounds", rounds_}, {"rounds_total", rounds_total_}};
}

void OracleStrategy::restore_state(const nlohmann::json& state) {
    // The allocation is rebuilt from sigma; a checkpoint cut into another number of
    // rounds belongs to another sigma or budget.
    if (state.at("rounds_total").get<uint32_t>() != rounds_total_)
        throw std::runtime_error("oracle checkpoint is of another allocation");
    rounds_ = state.at("rounds").get<uint32_t>();
}

}  // namespace aliquot
