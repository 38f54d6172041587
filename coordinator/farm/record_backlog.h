// RecordBacklog: writes to the run record (SQLite, checkpoints, EXR), kept in order and
// tried again with backoff when they fail. A full disk delays the record; it never loses
// what was merged, and the render goes on meanwhile.
//
// By default a write runs on the caller's thread when nothing waits. After
// start_writer(), every write runs on the backlog's own thread instead, in the order
// submitted: the caller (the coordinator, holding its lock) only queues it, so a
// checkpoint or an EXR that takes a second to write holds no one up.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace aliquot {

class RecordBacklog {
public:
    using Clock = std::chrono::steady_clock;
    using Write = std::function<void()>;

    RecordBacklog() = default;
    RecordBacklog(const RecordBacklog&) = delete;
    RecordBacklog& operator=(const RecordBacklog&) = delete;
    ~RecordBacklog() { stop_writer(); }

    // Without a writer thread: runs `write` now when nothing waits; otherwise, or when it
    // throws, queues it behind the writes that wait, so the record keeps its order. With
    // one: queues it for the writer. `what` names it in the log. Thread-safe.
    void submit(std::string what, Write write, Clock::time_point now = Clock::now());
    // Without a writer thread: tries the waiting writes in order once the backoff has
    // passed, stopping at the first that fails: half a second after a failure, doubling
    // up to 30 s. With one, the writer does this and retry() does nothing.
    void retry(Clock::time_point now = Clock::now());

    // Runs every later write (and those waiting) on a thread of the backlog's own.
    void start_writer();
    // Tries what waits once more, then ends the writer thread; writes still failing are
    // dropped (a restarted coordinator redoes them from its checkpoints). Idempotent.
    void stop_writer();
    // Waits until nothing waits or `timeout` passes; whether nothing waits.
    bool wait_idle(std::chrono::milliseconds timeout);

    size_t waiting() const;
    // Why the oldest waiting write failed; empty when everything is written.
    std::string warning() const;
    // Attempts that failed since the backlog began, retries included: a counter for the
    // coordinator's metrics, which only grows.
    uint64_t failures() const;

private:
    struct Pending {
        std::string what;
        Write write;
    };
    // Runs one write; the error message when it threw. Called without the lock.
    static bool run(Pending& p, std::string& error);
    // The bookkeeping after run(), under the lock.
    void note(const Pending& p, bool ok, const std::string& error, Clock::time_point now);
    void writer_main();

    mutable std::mutex mutex_;
    std::condition_variable wake_, idle_;
    std::deque<Pending> queue_;
    Clock::time_point next_try_{};
    Clock::duration delay_{};
    std::string warning_;
    uint64_t failures_ = 0;
    bool background_ = false, stopping_ = false, running_ = false;
    std::thread writer_;
};

}  // namespace aliquot
