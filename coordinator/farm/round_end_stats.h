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
    void add(const RoundEnd& end);
    double seconds() const;
    double cpu_seconds() const;
    double wait_seconds() const;
    uint64_t rounds() const;

private:
    mutable std::mutex mutex_;
    double seconds_ = 0, cpu_seconds_ = 0, wait_seconds_ = 0;
    uint64_t rounds_ = 0;
};

}  // namespace aliquot
