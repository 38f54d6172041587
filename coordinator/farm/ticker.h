// Ticker: a thread that calls `tick` every `period` until stopped (the coordinator's
// expiries, lost workers, records and retention). Nothing a tick throws ends the
// process: it is logged, and the next tick comes as usual.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace aliquot {

class Ticker {
public:
    Ticker(std::chrono::milliseconds period, std::function<void()> tick);
    ~Ticker() { stop(); }
    // Wakes the thread and waits for it; a tick under way ends first.
    void stop();

private:
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;
    std::thread thread_;
};

}  // namespace aliquot
