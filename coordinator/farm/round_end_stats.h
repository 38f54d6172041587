// What the coordinator's round ends cost, over all renders (bench/farm_scale, /metrics):
// the Complete calls that ended a round (the last job's merge, the error estimate, the
// record, the checkpoint copy, planning and cutting the next round), measured under the
// render's lock by a RoundEndMeter and summed here under a lock of its own, a leaf
// (docs/FARM.md, "Locks").
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>

#include "render_session.h"

namespace aliquot {

// One Complete call's round ends: none when `rounds` is 0.
struct RoundEnd {
    double seconds = 0, cpu_seconds = 0;
    uint32_t rounds = 0;
    // The workers waited through it: the render's next round had not been opened ahead
    // (render_session.h, "two rounds out"), so none of its jobs was out meanwhile.
    bool waited = false;
};

// Started before a merge under the render's lock, read after it, still under it.
class RoundEndMeter {
public:
    explicit RoundEndMeter(const RenderSession& session);
    RoundEnd finish(const RenderSession& session) const;

private:
    uint32_t rounds_before_;
    std::chrono::steady_clock::time_point began_;
    double began_cpu_;
};

class RoundEndStats {
public:
    struct Totals {
        double seconds = 0, cpu_seconds = 0;
        double wait_seconds = 0;  // of the round ends the workers waited through
        uint64_t rounds = 0;
    };
    void add(const RoundEnd& end);
    Totals totals() const;

private:
    mutable std::mutex mutex_;
    Totals totals_;
};

}  // namespace aliquot
