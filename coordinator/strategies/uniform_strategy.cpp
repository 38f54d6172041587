#include "uniform_strategy.h"

#include <algorithm>
#include <utility>

namespace aliquot {

UniformStrategy::UniformStrategy(uint32_t width, uint32_t height, uint32_t spp)
    : spp_(spp), pixels_(size_t(width) * height) {}

uint32_t UniformStrategy::round_spp(uint32_t done, uint32_t spp, size_t pixels) {
    // Growth keeps the number of rounds logarithmic; the cap (round_samples: an eighth
    // of the render, at least kRoundSamples) keeps a restart from tracing much again and
    // the merges a pixel few (each round merges every pixel once). Every round ends in a
    // barrier (its last job holds up the next round), so the first round holds
    // kFirstRoundSamples, not 1 spp: on a small image rounds of 1, 1, 2, 4 spp are
    // milliseconds of tracing each and their ends cost a two-worker farm a fifth of a
    // 64-spp render (docs/PERFORMANCE.md, farm efficiency). After it the render so far
    // grows kRoundGrowth-fold a round, not twofold: the first preview comes as soon, and
    // a 1920x1080 pixel is merged 5 times at 64 spp, not 7 (2, 14, then rounds of 16),
    // where the merges are most of the coordinator's CPU (docs/PERFORMANCE.md, "Fewer
    // rounds at small budgets").
    const size_t n = std::max<size_t>(pixels, 1);
    const uint64_t cap = std::max<uint64_t>(1, round_samples(uint64_t(spp) * n) / n);
    const uint64_t floor = std::max<uint64_t>(1, kFirstRoundSamples / n);
    const uint64_t grown = uint64_t(done) * (kRoundGrowth - 1);
    const uint64_t want = std::min<uint64_t>(std::max<uint64_t>(grown, floor), cap);
    return uint32_t(std::min<uint64_t>(want, spp - done));
}

std::optional<Round> UniformStrategy::next_round(const Accumulator&) {
    if (work_ahead_) std::exchange(work_ahead_, nullptr)();  // not taken: done here
    if (done_ >= spp_) return std::nullopt;
    const uint32_t n = round_spp(done_, spp_, pixels_);
    done_ += n;
    Round round{rounds_++, {}};
    // The very vector made ahead, whose jobs may be out already.
    if (ahead_.empty())
        round.spp.assign(pixels_, n);
    else
        round.spp = std::exchange(ahead_, {});
    if (done_ < spp_)
        work_ahead_ = [this, next = round_spp(done_, spp_, pixels_)] {
            ahead_.assign(pixels_, next);
        };
    return round;
}

std::function<void()> UniformStrategy::take_work_ahead() {
    return std::exchange(work_ahead_, nullptr);
}

}  // namespace aliquot

namespace aliquot {

nlohmann::json UniformStrategy::save_state() const {
    return {{"done_spp", done_}, {"rounds", rounds_}};
}

void UniformStrategy::restore_state(const nlohmann::json& state) {
    done_ = state.at("done_spp").get<uint32_t>();
    rounds_ = state.at("rounds").get<uint32_t>();
    work_ahead_ = nullptr;
    ahead_.clear();
}

}  // namespace aliquot
