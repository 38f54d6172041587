// Strategy: decides where a render's next samples go. It sees only the merged buffers at
// a round boundary (never arrival order or timings), so its decisions are deterministic.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "accumulator.h"

namespace aliquot {

class AuxSums;

// The least of round_samples (below), the most a round holds when a method is free to
// choose (uniform's growth stops there; adaptive's and oracle's deliveries are about
// that large). The coordinator's work at a round's end grows with the image's pixels
// (error estimate, checkpoint copy, cutting: about 25 ns a pixel), so a round must hold
// enough samples a pixel for that to stay small beside the tracing: at 2^22 a 1920x1080
// round was 2 spp, a tenth of a second on a 16-core farm, and its end took a third of
// the render (docs/PERFORMANCE.md). 2^25 is 16 spp there, and a few seconds of one
// two-core worker between checkpoints.
constexpr uint64_t kRoundSamples = uint64_t(1) << 25;

// The least a method's first round holds when it is free to choose (uniform's growth
// starts here): about a second of one two-core worker, so a small image's first preview
// still comes at once, and a round end's barrier is paid once, not every few
// milliseconds.
constexpr uint64_t kFirstRoundSamples = kRoundSamples / 8;

// A render's rounds where a method is free to choose hold at most round_samples(budget):
// kRoundSamples, or an eighth of the budget when that is more. Every round merges each
// pixel it covers once (~30-40 ns of the coordinator's a pixel), so rounds capped at
// kRoundSamples alone merged a 1920x1080 pixel 67 times at 1024 spp, and the merges, not
// the samples, were the coordinator's CPU (docs/PERFORMANCE.md, "rounds that grow with
// the budget"); with the cap growing with the budget a pixel is merged at most about
// log2(spp) + 7 times (uniform's rounds: 10 at 1080p 1024 spp, 5 at 64). A function of
// the budget alone, never of the farm, so the bits do not depend on who traces them. What
// it costs: a restart traces again at most an eighth of the render, and a small farm
// hears of a round's end, and may checkpoint, less often (docs/FARM.md, "How long a round
// is").
constexpr uint64_t kRoundsOfABudget = 8;
constexpr uint64_t round_samples(uint64_t budget) {
    return budget / kRoundsOfABudget > kRoundSamples ? budget / kRoundsOfABudget
                                                     : kRoundSamples;
}

struct Round {
    uint32_t index = 0;
    std::vector<uint32_t> spp;  // samples each pixel gets this round, row-major
    uint64_t total() const {
        uint64_t n = 0;
        for (uint32_t s : spp) n += s;
        return n;
    }
};

// A rectangle of pixels a strategy reasons about as one (Dammertz's tree leaves,
// adaptive's grid); kept so dashboards can draw the boundaries.
struct Bucket {
    PixelRect rect;
    double error = 0;        // the strategy's own error estimate for the bucket
    bool converged = false;  // Dammertz: E <= V reached
};

class Strategy {
public:
    virtual ~Strategy() = default;
    virtual std::string name() const = 0;
    // The next round given everything merged so far, or nullopt when the render is done.
    virtual std::optional<Round> next_round(const Accumulator& merged) = 0;
    // Work the last next_round left to do before the next round may be asked for, which
    // needs none of the round's results: planning that round ahead from what next_round
    // copied of the buffers (docs/STRATEGIES.md, "Planning ahead"), or taking the
    // buffers a plan will need. A caller that takes it may run it on any thread while
    // results merge, and must let it finish before calling the strategy again; work not
    // taken is done by the next next_round. Empty when there is none.
    virtual std::function<void()> take_work_ahead() { return {}; }
    // At a round end, before next_round: the work that plans the next round when that is
    // long (denoised's two OIDN passes, minutes on a large image), which the caller runs
    // off its lock, no round being out meanwhile. It copies what the plan reads of
    // `merged` and returns that work; the next next_round hands out the round it made
    // (and makes it itself when the work was not run). Empty: next_round plans in place.
    virtual std::function<void()> take_round_end(const Accumulator& /*merged*/) {
        return {};
    }
    // The render has ended: work handed out (take_work_ahead, take_round_end) may give
    // up early, its plan abandoned. The caller still waits for it to end.
    virtual void stop_work() {}
    // Whether the strategy holds a round planned before the last round's results merged:
    // its state then does not follow from the merged buffers alone. A checkpoint taken
    // then holds that round's counts too (round_planned_ahead, once its work has run),
    // given back by restore_planned_round after restore_state.
    virtual bool holds_planned_round() const { return false; }
    // The counts of the round planned ahead, once the work that plans it has run and
    // until the next_round that hands it out (which returns these very counts): a caller
    // may lease that round's jobs while the round before is still merging, and merge
    // their results after it. Null when no such round is held.
    virtual const std::vector<uint32_t>* round_planned_ahead() const { return nullptr; }

    // Samples the render expects to spend in all, for progress; an upper bound for
    // methods that stop early.
    virtual uint64_t planned_samples() const = 0;

    // The strategy's state between rounds, so that a restarted coordinator that restores
    // it with the checkpointed buffers makes exactly the decisions it would have made.
    virtual nlohmann::json save_state() const = 0;
    virtual void restore_state(const nlohmann::json& state) = 0;
    // After restore_state of a state saved while a round planned ahead was held: that
    // round's counts, as round_planned_ahead gave them. Throws std::runtime_error for
    // counts the state does not expect (a damaged or foreign checkpoint).
    virtual void restore_planned_round(std::vector<uint32_t> spp) {
        if (!spp.empty())
            throw std::runtime_error(name() + " plans no round ahead to restore");
    }

    // Whether the render must trace each sample's first hit (albedo, normal) into an
    // AuxSums beside its buffers: `denoised` gives them to Open Image Denoise.
    virtual bool wants_first_hits() const { return false; }
    // Those sums, given once by whoever merges, before the first next_round, when
    // wants_first_hits; they must outlive the strategy's last next_round.
    virtual void watch_first_hits(const AuxSums* /*first_hits*/) {}

    // Current buckets; empty for methods that allocate per pixel.
    virtual std::vector<Bucket> buckets() const { return {}; }
    // What the render should report when done, e.g. how much of the image a cap stopped
    // before it converged. Empty object when there is nothing to say.
    virtual nlohmann::json outcome() const { return nlohmann::json::object(); }
};

}  // namespace aliquot
