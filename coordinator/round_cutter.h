// Cutting a round into sample jobs: square tiles, each pixel's samples continuing from the
// number it already has, so sample indices never repeat across rounds.
#pragma once

#include <vector>

#include "accumulator.h"
#include "strategy.h"

namespace aliquot {

// Tiles of `tile` x `tile` pixels (smaller at the edges); tiles with no samples are skipped.
std::vector<SampleJob> cut_round(const Round& round, const Accumulator& merged,
                                 uint32_t tile = 32);

}  // namespace aliquot
