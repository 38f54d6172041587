// Checkpoint: a render's merged buffers and strategy state at a round boundary, on disk,
// so a restarted coordinator continues exactly where the last checkpointed round left it
// (and, rounds being deterministic, re-runs the rounds after it to the same bytes).
#pragma once

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

#include "accumulator.h"
#include "aux_sums.h"

namespace aliquot {

struct Checkpoint {
    Accumulator merged;
    nlohmann::json strategy_state;
    uint32_t rounds_done = 0;
    double seconds = 0;
    // The counts of the round the strategy planned before these buffers' last round had
    // merged (Strategy::round_planned_ahead), or empty: restored with the state, so the
    // render goes on from a round end where a round was planned ahead as from any other.
    std::vector<uint32_t> planned_round;
    // The first-hit sums of a render that keeps them (RenderSpec::aux), or none.
    AuxSums aux;
};

// What a round end copies for the record's writer: the buffers as the file holds them,
// the merged sums without what the accumulator derives from them (sample and ray counts,
// half differences, variances: loading recomputes them), 80 bytes a pixel where a copy
// of the accumulator took 112 (166 MB against 232 at 1920x1080, under the render's lock).
struct CheckpointSnapshot {
    uint32_t width = 0, height = 0;
    std::vector<PixelSums> sums;  // row-major, width x height
    AuxSums aux;                  // the first-hit sums of a render that keeps them
    nlohmann::json strategy_state;
    uint32_t rounds_done = 0;
    double seconds = 0;
    std::vector<uint32_t> planned_round;  // as in Checkpoint

    // Takes the sums of `merged` and `aux`, reusing this one's memory when the sizes
    // match, the bytes copied in bands on the pool's threads.
    void copy_buffers(const Accumulator& merged, const AuxSums& aux);
};

// Written to a temporary file and renamed over `path`: a crash leaves the old checkpoint
// or the new one, never half of one. Both give the same bytes for the same buffers.
void save_checkpoint(const std::filesystem::path& path,
                     const CheckpointSnapshot& snapshot);
void save_checkpoint(const std::filesystem::path& path, const Checkpoint& checkpoint);
// nullopt when there is no checkpoint; throws std::runtime_error for a damaged one.
std::optional<Checkpoint> load_checkpoint(const std::filesystem::path& path);

// Whether a round's checkpoint is due: checkpoints may take at most 1/kCheckpointShare of
// a render's time. A checkpoint holds the whole buffers (80 bytes a pixel) and Dammertz
// runs thousands of short rounds: one per round wrote gigabytes a render. `since_last` is
// the time since the last checkpoint ended, `last_cost` how long writing it took (0: none
// yet).
inline constexpr double kCheckpointShare = 20;
bool checkpoint_due(double since_last_seconds, double last_cost_seconds);
// What a render's first checkpoint is expected to cost before one was timed: its bytes
// at kFirstCheckpointBytesPerSecond. The first is due once the render has run
// kCheckpointShare times that (checkpoint_due with the render's seconds), not at its
// first round end: a 1920x1080 render's first round ended ~0.1 s in, and its copy and
// write then were a tenth to a third of a 64-spp render's coordinator CPU on 16 worker
// cores.
inline constexpr double kFirstCheckpointBytesPerSecond = 1e9;
double expected_checkpoint_seconds(uint64_t pixels, bool first_hits);

}  // namespace aliquot
