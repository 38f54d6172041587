// What clients see of a render and of a worker: the one shape the API's JSON and proto
// are made from (coordinator/api's render_json and render_proto).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "render_state.h"

namespace aliquot {

class RenderSession;

// A render as clients see it. The state is the C++ enum; its spellings ("running", ...)
// are lifecycle/render_state.h's alone.
struct RenderInfo {
    std::string id, scene_name, method, strategy_json, error, outcome_json;
    RenderState state = RenderState::Queued;
    uint32_t width = 0, height = 0;
    uint64_t seed = 0, samples_done = 0, samples_planned = 0, rays = 0;
    uint32_t rounds_done = 0;
    int32_t priority = 0;
    double seconds = 0, samples_per_second = 0;
    double error_estimate = -1, error_vs_reference = -1;
    // The last round's mean bias against the reference and its SE (RoundSummary).
    std::optional<double> mean_bias, mean_bias_se;
    int64_t created_ms = 0, finished_ms = 0;
    std::string name;  // RenderSpec::name
    // While the render is Queued (no job leased yet), its place in the queue: 1 is
    // leased next (RenderQueue); 0 otherwise.
    uint32_t queue_position = 0;
};

struct WorkerStatus {
    std::string name, state;  // idle | busy | lost
    uint32_t threads = 0;
    std::vector<std::string> leases;
    uint64_t samples_traced = 0;
    double samples_per_second = 0;
    int64_t last_seen_ms = 0;
    std::string host, version;  // as the worker said when it registered
    uint32_t failures = 0;      // jobs it reported failed, every render's
};

// A render in memory as clients see it; under its lock.
RenderInfo info_of(const RenderSession& session, int32_t priority);

}  // namespace aliquot
