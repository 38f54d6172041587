#include "worker_loop.h"

#include <cstdio>
#include <functional>
#include <new>
#include <optional>
#include <random>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "courier.h"
#include "log_line.h"
#include "trace_job.h"

namespace aliquot {

namespace {

using Millis = std::chrono::milliseconds;

// Waits that double from `initial` up to `max`, each drawn between half and all of the
// current step so that workers retrying together spread out. The jitter only moves
// retries in time: it never touches what is traced.
class Backoff {
public:
    Backoff(Millis initial, Millis max)
        : initial_(std::max(initial, Millis(1))),
          max_(std::max(max, initial_)),
          step_(initial_),
          rng_(uint32_t(std::hash<std::thread::id>{}(std::this_thread::get_id()))) {}

    Millis next() {
        const auto half = step_.count() / 2;
        const Millis wait(half + std::uniform_int_distribution<int64_t>(0, half)(rng_));
        step_ = std::min(step_ * 2, max_);
        return wait;
    }
    void reset() { step_ = initial_; }

private:
    Millis initial_, max_, step_;
    std::minstd_rand rng_;
};

int64_t steady_nanos() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

// The slot of beats_ the calling thread marks, set when a loop's thread starts.
thread_local std::atomic<int64_t>* beat_slot = nullptr;

std::string seconds_text(Millis d) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f s", double(d.count()) / 1000.0);
    return text;
}

}  // namespace

WorkerLoop::WorkerLoop(WorkerLink& link, WorkerOptions options)
    : link_(link), options_(std::move(options)) {
    beat_slots_ = size_t(std::max(options_.threads, 1)) + 1;
    beats_ = std::make_unique<std::atomic<int64_t>[]>(beat_slots_);
    const int64_t now = steady_nanos();
    for (size_t i = 0; i < beat_slots_; ++i) beats_[i] = now;
}

void WorkerLoop::beat() const {
    if (beat_slot) *beat_slot = steady_nanos();
}

std::chrono::steady_clock::time_point WorkerLoop::stalest_beat() const {
    // Before the threads start, the registering thread is the only one.
    const size_t slots = threads_started_ ? beat_slots_ : 1;
    int64_t stalest = beats_[0];
    for (size_t i = 1; i < slots; ++i) stalest = std::min<int64_t>(stalest, beats_[i]);
    return std::chrono::steady_clock::time_point(std::chrono::nanoseconds(stalest));
}

void WorkerLoop::log(const std::string& line) const {
    if (!options_.quiet)
        write_log_line("worker",
                       {log_text("worker", options_.name), log_text("message", line)});
}

void WorkerLoop::sleep_unless_stopping(std::chrono::milliseconds duration) {
    // Short steps, so that stop() is honoured promptly.
    // A deliberate wait is not a stuck thread: each step is a beat.
    const auto until = std::chrono::steady_clock::now() + duration;
    while (!stopping_ && std::chrono::steady_clock::now() < until) {
        beat();
        std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
            Millis(50), until - std::chrono::steady_clock::now()));
    }
}

bool WorkerLoop::release(uint64_t lease_id) {
    std::lock_guard lock(held_mutex_);
    return held_.erase(lease_id) > 0;
}

bool WorkerLoop::register_again(uint64_t seen) {
    std::lock_guard lock(register_mutex_);
    if (registrations_ != seen) return false;  // another thread did, after our call began
    const Registration r =
        link_.register_worker(options_.name, uint32_t(options_.threads));
    {
        std::lock_guard session_lock(session_mutex_);
        session_ = r.session;
    }
    lease_ms_ = r.lease_ms;
    ++registrations_;
    return true;
}

std::string WorkerLoop::session() const {
    std::lock_guard lock(session_mutex_);
    return session_;
}

void WorkerLoop::refused(const LinkRefused& e) {
    {
        std::lock_guard lock(session_mutex_);
        if (refused_.empty()) refused_ = e.what();
    }
    stopping_ = true;
}

bool WorkerLoop::reregister(uint64_t seen, bool& announced) {
    try {
        if (register_again(seen))
            log("registered again with " + std::to_string(options_.threads) + " threads");
        return true;
    } catch (const LinkRefused& e) {
        refused(e);  // the token was changed or revoked since we started
        return false;
    } catch (const std::exception& e) {
        if (!announced) log(std::string("cannot register, retrying: ") + e.what());
        announced = true;
        return false;
    }
}

void WorkerLoop::run() {
    Backoff wait(options_.backoff_initial, options_.reconnect_max);
    bool announced = false;
    beat_slot = &beats_[0];  // registering: until the tracing threads start
    while (!stopping_) {
        beat();
        try {
            register_again(registrations_);
            log("registered with " + std::to_string(options_.threads) + " threads");
            break;
        } catch (const LinkRefused& e) {
            refused(e);
        } catch (const std::exception& e) {
            // Unreachable, or an answer this worker cannot use: wait and try again.
            if (!announced)
                log(std::string("coordinator unavailable, retrying: ") + e.what());
            announced = true;
            sleep_unless_stopping(wait.next());
        }
    }
    beat_slot = nullptr;
    const int64_t now = steady_nanos();
    for (size_t i = 0; i < beat_slots_; ++i) beats_[i] = now;
    threads_started_ = true;
    {
        // Nothing escapes a thread: a thread that cannot go on (its courier's thread not
        // had, memory) stops the worker with the reason instead of aborting it.
        const auto guarded = [this](const auto& body) {
            try {
                body();
            } catch (const std::exception& e) {
                broke(std::string("a thread stopped: ") + e.what());
            }
        };
        std::vector<std::jthread> threads;
        std::optional<std::jthread> keeper;
        try {
            for (int t = 0; t < std::max(options_.threads, 1) && !stopping_; ++t)
                threads.emplace_back([this, t, guarded] {
                    beat_slot = &beats_[size_t(t)];
                    guarded([this] { thread_main(); });
                });
            keeper.emplace([this, guarded] {
                beat_slot = &beats_[beat_slots_ - 1];
                guarded([this] { keeper_main(); });
            });
        } catch (const std::exception& e) {
            // Those started end at once (they wait for stopping_) and are joined here.
            broke(std::string("cannot start a thread: ") + e.what());
        }
    }  // every thread has ended
    std::lock_guard lock(session_mutex_);
    if (!refused_.empty()) throw LinkRefused(refused_);
    if (!broken_.empty()) throw std::runtime_error(broken_);
}

void WorkerLoop::broke(const std::string& why) {
    {
        std::lock_guard lock(session_mutex_);
        if (broken_.empty()) broken_ = why;
    }
    stopping_ = true;
}

// What one tracing thread carries from lease to lease: two kinds of retry, each waiting
// longer each time (reaching the coordinator; jobs that fail here or answers the
// coordinator refuses), whether "cannot get a lease" was logged, and the registrations
// seen when this lease was asked for.
struct WorkerLoop::Retries {
    Backoff unreachable, faults;
    bool announced = false;
    uint64_t registrations = 0;
};

// The outcome of tracing one lease.
struct WorkerLoop::Traced {
    std::optional<SampleJobResult> result;
    std::string failure;        // why this worker cannot trace it; empty otherwise
    bool unreachable = false;   // the coordinator went away while fetching the scene
    bool session_gone = false;  // the coordinator restarted: the lease went with it
};

void WorkerLoop::thread_main() {
    enable_flush_to_zero();
    Retries retries{Backoff(options_.backoff_initial, options_.reconnect_max),
                    Backoff(options_.backoff_initial, options_.failure_max)};
    // While a job is traced, its courier returns the last one's sums and leases the next
    // (docs/FARM.md, "A job in flight while the next is traced"). Whatever it is doing,
    // only one of the two threads uses `retries` at a time: the tracing thread touches
    // it only while the courier is idle.
    Courier courier;
    std::optional<LeaseGrant> grant;  // the lease this thread traces next
    while (!stopping_) {
        beat();
        // The courier is idle here whenever there is no grant: a call it was sent with a
        // job in hand left that job as the next grant.
        if (!grant) grant = next_lease(retries);
        if (!grant) continue;
        hold(grant->lease_id);
        // Asked without waiting: a long-poll here could wait for the end of the round
        // that this very job ends.
        if (!courier.busy()) courier.send([&] { return lease_ahead(); });
        Traced traced = trace(*grant);
        std::optional<LeaseGrant> ahead = courier.wait();  // held already
        if (traced.session_gone) {
            // The coordinator restarted: what it leased under the old session is gone.
            release(grant->lease_id);
            if (ahead) release(ahead->lease_id);
            ahead.reset();
            reregister(retries.registrations, retries.announced);
        } else if (traced.result && ahead) {
            release(grant->lease_id);  // from here on the result answers for the lease
            courier.send([this, done = std::move(*grant),
                          result = std::move(*traced.result), &retries] {
                std::optional<LeaseGrant> next =
                    return_result(done, result, Millis(0), retries);
                // Held at once, so the keeper renews it however long this trace takes.
                if (next) hold(next->lease_id);
                return next;
            });
        } else if (traced.result) {
            // Nothing else to trace: the return may wait for the next job.
            release(grant->lease_id);
            ahead = return_result(*grant, *traced.result, options_.lease_wait, retries);
        } else {
            // A job not traced (this worker cannot, or is stopping): the one leased
            // ahead goes back at once, not held through the wait that follows.
            if (ahead) give_back(*ahead);
            ahead.reset();
            hand_back(*grant, traced, retries);
        }
        grant = std::move(ahead);
    }
    // Stopping: leases not yet begun are given back at once.
    if (grant) give_back(*grant);
    if (std::optional<LeaseGrant> last = courier.wait()) give_back(*last);
}

void WorkerLoop::give_back(const LeaseGrant& untraced) {
    release(untraced.lease_id);
    try {
        link_.abandon(session(), untraced.lease_id);
    } catch (const std::exception&) {
        // It expires on its own.
    }
}

void WorkerLoop::hold(uint64_t lease_id) {
    std::lock_guard lock(held_mutex_);
    held_.insert(lease_id);
}

std::optional<LeaseGrant> WorkerLoop::lease_ahead() {
    try {
        std::optional<LeaseGrant> grant = link_.lease(session(), Millis(0));
        if (grant) hold(grant->lease_id);
        return grant;
    } catch (const LinkRefused& e) {
        refused(e);
    } catch (const std::exception&) {
        // Unreachable, or a coordinator that forgot us: the tracing thread's own next
        // call meets it again, and retries as it does.
    }
    return std::nullopt;
}

std::optional<LeaseGrant> WorkerLoop::next_lease(Retries& retries) {
    retries.registrations = registrations_;
    const auto asked = std::chrono::steady_clock::now();
    std::optional<LeaseGrant> grant;
    try {
        grant = link_.lease(session(), options_.lease_wait);
        if (retries.announced) log("coordinator back");
        retries.announced = false;
    } catch (const WorkerUnknown&) {
        // The coordinator restarted without us: register again, with our threads.
        if (!reregister(retries.registrations, retries.announced))
            sleep_unless_stopping(retries.unreachable.next());
        return std::nullopt;
    } catch (const LinkRefused& e) {
        refused(e);
        return std::nullopt;
    } catch (const std::exception& e) {
        // Unreachable, or an answer this worker cannot read: wait and ask again; a worker
        // thread never dies of what the coordinator said.
        if (!retries.announced)
            log(std::string("cannot get a lease, retrying: ") + e.what());
        retries.announced = true;
        sleep_unless_stopping(retries.unreachable.next());
        return std::nullopt;
    }
    // A long-poll that ended early with nothing (a coordinator shutting down, a link that
    // does not wait) is not asked again at once, nor sooner each time.
    if (!grant && std::chrono::steady_clock::now() - asked < options_.lease_wait / 2) {
        sleep_unless_stopping(retries.unreachable.next());
        return std::nullopt;
    }
    retries.unreachable.reset();
    return grant;
}

WorkerLoop::Traced WorkerLoop::trace(const LeaseGrant& grant) {
    Traced out;
    try {
        auto scene = scenes_.get(grant.scene_hash, [&](const std::string& h) {
            return link_.fetch_scene(session(), h);
        });
        out.result =
            trace_sample_job(*scene->tracer, grant.geometry, grant.job, 1, &stopping_);
    } catch (const JobCancelled&) {
        // Stopping: the lease is given back by hand_back.
    } catch (const WorkerUnknown&) {
        out.session_gone = true;
    } catch (const LinkUnavailable& e) {
        log(std::string("lost the coordinator: ") + e.what());
        out.unreachable = true;
    } catch (const std::bad_alloc&) {
        // A scene too large for this worker's memory now (what it took is freed by now):
        // reported as any other job it cannot trace. Short enough to need no allocation.
        out.failure = "out of memory";
    } catch (const std::exception& e) {
        // A scene that does not load here, or tracing that threw: this worker cannot
        // trace the job. Reported by hand_back, so that another worker gets it and a job
        // nobody can trace fails its render instead of going round forever.
        out.failure = *e.what() ? e.what() : "tracing failed";
    } catch (...) {
        out.failure = "tracing failed with an unknown exception";
    }
    return out;
}

std::optional<LeaseGrant> WorkerLoop::return_result(const LeaseGrant& grant,
                                                    const SampleJobResult& result,
                                                    Millis wait, Retries& retries) {
    std::optional<LeaseGrant> next;
    try {
        // The next lease rides on the reply: one round trip a job (docs/FARM.md).
        const CompleteOutcome outcome =
            link_.complete_and_lease(session(), grant.lease_id, result, wait, next);
        if (outcome.status == CompleteStatus::Merged) {
            samples_traced_ += result.total_samples();
            ++jobs_done_;
            retries.faults.reset();
        } else if (outcome.status == CompleteStatus::Rejected) {
            const Millis wait = retries.faults.next();
            log("result rejected: " + outcome.message + "; next lease in " +
                seconds_text(wait));
            sleep_unless_stopping(wait);
        }
    } catch (const WorkerUnknown&) {
        // The coordinator restarted since this lease; the job is traced again.
        reregister(retries.registrations, retries.announced);
    } catch (const LinkUnavailable& e) {
        log(std::string("lost the coordinator: ") + e.what());
        sleep_unless_stopping(retries.unreachable.next());
    } catch (const std::exception& e) {
        const Millis wait = retries.faults.next();
        log(std::string("cannot return a result: ") + e.what() + "; next lease in " +
            seconds_text(wait));
        sleep_unless_stopping(wait);
    }
    return next;
}

void WorkerLoop::hand_back(const LeaseGrant& grant, const Traced& traced,
                           Retries& retries) {
    // Still held: not traced to the end. Reported or given back outside the lock (an
    // RPC).
    if (!release(grant.lease_id)) return;
    if (!traced.failure.empty()) {
        ++jobs_failed_;
        const Millis wait = retries.faults.next();
        log("cannot trace a job of " + grant.render_id + ": " + traced.failure +
            "; reported, next lease in " + seconds_text(wait));
        try {
            link_.fail(session(), grant.lease_id, traced.failure);
        } catch (const std::exception&) {
            // The lease expires on its own and the job goes to someone else.
        }
        sleep_unless_stopping(wait);
        return;
    }
    try {
        link_.abandon(session(), grant.lease_id);
    } catch (const std::exception&) {
        // The lease expires on its own.
    }
    if (traced.unreachable) sleep_unless_stopping(retries.unreachable.next());
}

void WorkerLoop::keeper_main() {
    while (!stopping_) {
        beat();
        sleep_unless_stopping(
            std::chrono::milliseconds(std::max<uint32_t>(lease_ms_ / 3, 100)));
        std::set<uint64_t> held;
        {
            std::lock_guard lock(held_mutex_);
            held = held_;
        }
        for (uint64_t lease : held) {
            try {
                link_.renew(session(), lease);
            } catch (const std::exception&) {
                break;  // unreachable: the next period tries again, or the leases expire
            }
        }
    }
}

}  // namespace aliquot
