// Checkpoint: a render's merged buffers and strategy state at a round boundary, on disk, so
// a restarted coordinator continues exactly where the last complete round left it.
#pragma once

#include <filesystem>
#include <optional>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "accumulator.h"

namespace aliquot {

struct Checkpoint {
    Accumulator merged;
    nlohmann::json strategy_state;
    uint32_t rounds_done = 0;
    double seconds = 0;
};

// Written to a temporary file and renamed over `path`: a crash leaves the old checkpoint
// or the new one, never half of one.
void save_checkpoint(const std::filesystem::path& path, const Checkpoint& checkpoint);
// nullopt when there is no checkpoint; throws std::runtime_error for a damaged one.
std::optional<Checkpoint> load_checkpoint(const std::filesystem::path& path);

}  // namespace aliquot
