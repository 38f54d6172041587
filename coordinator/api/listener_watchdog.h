// Notices a listener that has stopped accepting connections while the process goes on:
// gRPC 1.51's listener gives up for good after one failed accept (EMFILE in a connection
// flood), and a coordinator that is up but deaf looks healthy to every check but a new
// connection (docs/SECURITY.md, "gRPC listener").
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace aliquot {

class ListenerWatchdog {
public:
    // Every `period`, `reached()` is asked whether a new connection is answered; after
    // `failures` noes in a row `deaf()` is called (and the count starts again). Both run
    // on the watchdog's thread and must not throw.
    ListenerWatchdog(std::chrono::milliseconds period, int failures,
                     std::function<bool()> reached, std::function<void()> deaf);
    // Stops the thread, waiting for a probe in progress.
    ~ListenerWatchdog();
    ListenerWatchdog(const ListenerWatchdog&) = delete;
    ListenerWatchdog& operator=(const ListenerWatchdog&) = delete;

private:
    void run();

    const std::chrono::milliseconds period_;
    const int failures_;
    std::function<bool()> reached_;
    std::function<void()> deaf_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;
    std::thread thread_;
};

}  // namespace aliquot
