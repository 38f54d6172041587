// WorkerLoop: a worker's life. Each of its threads asks for a lease, traces the job and
// returns the sums; a keeper thread renews held leases. A coordinator that goes away is
// waited for with backoff, never a crash; a job that cannot be traced is reported with
// Fail and followed by a growing wait; stop() gives held leases back.
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>

#include "lease.h"
#include "scene_cache.h"

namespace aliquot {

struct WorkerOptions {
    std::string name;
    int threads = 1;
    std::chrono::milliseconds lease_wait{2000};  // long-poll length
    bool quiet = false;                          // no log lines (embedded render)
    // Every retry waits, doubling from `backoff_initial` (each wait jittered down to
    // half): up to `reconnect_max` while the coordinator cannot be reached (so a worker
    // is back soon after it is), up to `failure_max` after a job this worker could not
    // trace or an error reply.
    std::chrono::milliseconds backoff_initial{200};
    std::chrono::milliseconds reconnect_max{1000};
    std::chrono::milliseconds failure_max{10000};
};

class WorkerLoop {
public:
    WorkerLoop(WorkerLink& link, WorkerOptions options);

    // Runs until stop() is called. Thread-safe to call stop() from any thread. Throws
    // LinkRefused, once every thread has ended, when the coordinator refused this
    // worker's token: no retry can help; std::runtime_error when a thread could not be
    // started or one stopped on an exception (no thread of resources, no memory), so
    // that the process exits non-zero and its supervisor starts it again.
    void run();
    void stop() { stopping_ = true; }

    // When every one of this worker's threads (the tracing threads and the lease keeper)
    // last showed it is not stuck: each marks each turn of its loop and each step of a
    // deliberate wait; its calls to the coordinator are bounded by deadlines, and a job's
    // trace by its size. `aliquot worker --health-file` turns it into a liveness signal.
    std::chrono::steady_clock::time_point stalest_beat() const;

    uint64_t samples_traced() const { return samples_traced_; }
    uint64_t jobs_done() const { return jobs_done_; }
    // Jobs this worker reported it could not trace.
    uint64_t jobs_failed() const { return jobs_failed_; }

private:
    struct Retries;
    struct Traced;
    // One tracing thread: lease, trace, then return the result or hand the lease back;
    // the next job is leased, and the last one's result returned, while it traces.
    void thread_main();
    // A lease, or nullopt after waiting as the failure asked (then ask again).
    std::optional<LeaseGrant> next_lease(Retries& retries);
    // A lease if there is work now, without waiting; nullopt on any failure (the
    // tracing thread's next call meets it again and retries).
    std::optional<LeaseGrant> lease_ahead();
    // Marks a lease held: the keeper renews it until release().
    void hold(uint64_t lease_id);
    // A lease not begun, released and abandoned: re-issued at once.
    void give_back(const LeaseGrant& untraced);
    Traced trace(const LeaseGrant& grant);
    // Returns the result and, when it merged, the next lease with it, waiting up to
    // `wait` for one (nullopt: ask).
    std::optional<LeaseGrant> return_result(const LeaseGrant& grant,
                                            const SampleJobResult& result,
                                            std::chrono::milliseconds wait,
                                            Retries& retries);
    // A lease not traced to the end: reported as failed (with why) or abandoned.
    void hand_back(const LeaseGrant& grant, const Traced& traced, Retries& retries);
    void keeper_main();
    // Marks the calling thread alive now (its slot in beats_; nothing for a thread
    // without one).
    void beat() const;
    void log(const std::string& line) const;
    void sleep_unless_stopping(std::chrono::milliseconds duration);
    // Registers (again) unless another thread did since it saw `seen` registrations;
    // whether this call did. Throws what the link throws.
    bool register_again(uint64_t seen);
    // After WorkerUnknown (the coordinator restarted without us): registers again, with
    // our threads; false (logged once) when that failed too.
    bool reregister(uint64_t seen, bool& announced);
    // The session from the last registration: every call carries it.
    std::string session() const;
    // Drops the lease from the held set; whether it was still there.
    bool release(uint64_t lease_id);
    // Remembers why the coordinator refused this worker and stops every thread.
    void refused(const LinkRefused& e);
    // Remembers why a thread could not start or went on no longer, and stops every
    // thread.
    void broke(const std::string& why);

    WorkerLink& link_;
    WorkerOptions options_;
    SceneCache scenes_;
    std::atomic<bool> stopping_{false};
    std::atomic<uint32_t> lease_ms_{30000};
    std::atomic<uint64_t> samples_traced_{0}, jobs_done_{0}, jobs_failed_{0};
    std::mutex register_mutex_;
    std::atomic<uint64_t> registrations_{0};
    mutable std::mutex session_mutex_;
    std::string session_;
    std::string refused_;  // under session_mutex_: why run() ends with LinkRefused
    std::string broken_;   // under session_mutex_: why run() ends with runtime_error
    std::mutex held_mutex_;
    std::set<uint64_t> held_;
    // Per thread, steady-clock nanoseconds of its last beat: the tracing threads', then
    // the keeper's; the first is the registering thread's until the tracing threads
    // start.
    std::unique_ptr<std::atomic<int64_t>[]> beats_;
    size_t beat_slots_ = 0;
    std::atomic<bool> threads_started_{false};
};

}  // namespace aliquot
