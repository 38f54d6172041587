#include "stream_watchdog.h"

#include <grpcpp/server_context.h>

#include <algorithm>

namespace aliquot {

StreamWatchdog::StreamWatchdog(std::chrono::milliseconds grace, size_t min_rate)
    : grace_(grace),
      min_rate_(std::max<size_t>(min_rate, 1)),
      thread_([this] { run(); }) {}

StreamWatchdog::~StreamWatchdog() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    wake_.notify_all();
    thread_.join();
}

StreamWatchdog::Clock::time_point StreamWatchdog::due(size_t bytes) const {
    const std::chrono::duration<double> taking(double(bytes) / double(min_rate_));
    return Clock::now() + grace_ + std::chrono::duration_cast<Clock::duration>(taking);
}

StreamWatchdog::WatchedWrite::WatchedWrite(StreamWatchdog& watchdog,
                                           grpc::ServerContext& call,
                                           Clock::time_point deadline)
    : watchdog_(watchdog), call_(call) {
    bool first;
    {
        std::lock_guard lock(watchdog_.mutex_);
        entry_ = watchdog_.writes_.emplace(deadline, this);
        first = entry_ == watchdog_.writes_.begin();
    }
    // Only a write due before every other changes how long the watchdog sleeps.
    if (first) watchdog_.wake_.notify_all();
}

StreamWatchdog::WatchedWrite::~WatchedWrite() {
    // Under the mutex: once this returns, the watchdog no longer touches the call,
    // which may end at once.
    std::lock_guard lock(watchdog_.mutex_);
    if (watched_) watchdog_.writes_.erase(entry_);
}

void StreamWatchdog::run() {
    std::unique_lock lock(mutex_);
    while (!stopping_) {
        if (writes_.empty()) {
            wake_.wait(lock);
            continue;
        }
        const auto first = writes_.begin();
        // A copy: the write may end, and its entry go, while this waits.
        const Clock::time_point due = first->first;
        if (Clock::now() < due) {
            // Woken early by a new write (perhaps due sooner) or by stopping.
            wake_.wait_until(lock, due);
            continue;
        }
        // Overdue: its client takes less than the pace. Cancelling fails the blocked
        // Write (and any later one) at once; the handler returns and frees its place.
        WatchedWrite* overdue = first->second;
        overdue->watched_ = false;
        writes_.erase(first);
        overdue->call_.TryCancel();
    }
}

}  // namespace aliquot
