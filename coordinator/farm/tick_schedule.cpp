#include "tick_schedule.h"

#include <algorithm>

namespace aliquot {

TickChores TickSchedule::next() {
    std::lock_guard lock(mutex_);
    TickChores due;
    due.sweep_worker_rows = ticks_ % 300 == 0;
    ++ticks_;
    due.wal_checkpoint = ticks_ % 50 == 0;
    const auto now = std::chrono::steady_clock::now();
    const auto every = std::clamp<std::chrono::milliseconds>(
        keep_finished_ / 4, std::chrono::seconds(1), std::chrono::minutes(1));
    if (keep_finished_.count() > 0 && (ticks_ == 1 || now - last_retention_ >= every)) {
        due.retention = true;
        last_retention_ = now;
    }
    return due;
}

}  // namespace aliquot
