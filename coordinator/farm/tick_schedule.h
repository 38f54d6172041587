// TickSchedule: which of the coordinator's periodic chores a tick (every 200 ms) does.
// Its own lock, a leaf: tick() runs on the ticker's thread and in tests and at shutdown.
#pragma once

#include <chrono>
#include <mutex>

namespace aliquot {

struct TickChores {
    bool sweep_worker_rows =
        false;                    // rows of workers long silent: the first, then ~1/min
    bool wal_checkpoint = false;  // every 50th tick, ~10 s
    // Finished renders past keep_finished deleted: at the first tick, then once a minute,
    // or a quarter of keep_finished when that is shorter (at least a second), so that a
    // render is kept about as long as asked.
    bool retention = false;
};

class TickSchedule {
public:
    explicit TickSchedule(std::chrono::milliseconds keep_finished)
        : keep_finished_(keep_finished) {}
    // This tick's chores; each call is one tick.
    TickChores next();

private:
    const std::chrono::milliseconds keep_finished_;
    std::mutex mutex_;
    int ticks_ = 0;
    std::chrono::steady_clock::time_point last_retention_{};
};

}  // namespace aliquot
