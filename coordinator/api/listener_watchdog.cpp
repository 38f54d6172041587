#include "listener_watchdog.h"

namespace aliquot {

ListenerWatchdog::ListenerWatchdog(std::chrono::milliseconds period, int failures,
                                   std::function<bool()> reached,
                                   std::function<void()> deaf)
    : period_(period),
      failures_(failures),
      reached_(std::move(reached)),
      deaf_(std::move(deaf)),
      thread_([this] { run(); }) {}

ListenerWatchdog::~ListenerWatchdog() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    wake_.notify_all();
    thread_.join();
}

void ListenerWatchdog::run() {
    int failed = 0;
    std::unique_lock lock(mutex_);
    while (!wake_.wait_for(lock, period_, [this] { return stopping_; })) {
        lock.unlock();
        failed = reached_() ? 0 : failed + 1;
        if (failed >= failures_) {
            deaf_();
            failed = 0;
        }
        lock.lock();
    }
}

}  // namespace aliquot
