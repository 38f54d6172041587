// RecordBacklog: writes to the run record (SQLite, EXR) that failed, kept in order and
// tried again with backoff. A full disk delays the record; it never loses what was
// merged, and the render goes on meanwhile.
#pragma once

#include <chrono>
#include <deque>
#include <functional>
#include <string>

namespace aliquot {

class RecordBacklog {
public:
    using Clock = std::chrono::steady_clock;
    using Write = std::function<void()>;

    // Runs `write` now when nothing waits; otherwise, or when it throws, queues it behind
    // the writes that wait, so the record keeps its order. `what` names it in the log.
    void submit(std::string what, Write write, Clock::time_point now = Clock::now());
    // Tries the waiting writes in order once the backoff has passed, stopping at the
    // first that fails: half a second after a failure, doubling up to 30 s.
    void retry(Clock::time_point now = Clock::now());

    size_t waiting() const { return queue_.size(); }
    // Why the oldest waiting write failed; empty when everything is written.
    const std::string& warning() const { return warning_; }

private:
    struct Pending {
        std::string what;
        Write write;
    };
    bool attempt(Pending& p, Clock::time_point now);

    std::deque<Pending> queue_;
    Clock::time_point next_try_{};
    Clock::duration delay_{};
    std::string warning_;
};

}  // namespace aliquot
