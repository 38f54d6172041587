// The embedded render: the coordinator's round loop run in-process, sample jobs traced by
// local threads, no sockets. Same strategies, same jobs, same bytes as the farm.
#pragma once

#include <functional>

#include "accumulator.h"
#include "strategy.h"

namespace aliquot {

struct RenderProgress {
    uint32_t round = 0;
    uint64_t samples_done = 0;
    uint64_t samples_planned = 0;
    double seconds = 0;
};
using ProgressFn = std::function<void(const RenderProgress&)>;

struct RenderStats {
    uint32_t rounds = 0;
    double seconds = 0;
    uint64_t samples = 0;
    uint64_t rays = 0;
    uint64_t nonfinite = 0;
};

// Runs `strategy` to completion, merging into `merged` (which may already hold rounds).
RenderStats render_locally(const PathTracer& tracer, const RenderGeometry& geometry,
                           Strategy& strategy, Accumulator& merged, int threads,
                           const ProgressFn& progress = {});

}  // namespace aliquot
