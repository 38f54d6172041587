#include "worker_loop.h"

#include <cstdio>
#include <functional>
#include <random>
#include <thread>
#include <vector>

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

std::string seconds_text(Millis d) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f s", double(d.count()) / 1000.0);
    return text;
}

}  // namespace

WorkerLoop::WorkerLoop(WorkerLink& link, WorkerOptions options)
    : link_(link), options_(std::move(options)) {}

void WorkerLoop::log(const std::string& line) const {
    if (!options_.quiet)
        std::fprintf(stderr, "worker %s: %s\n", options_.name.c_str(), line.c_str());
}

void WorkerLoop::sleep_unless_stopping(std::chrono::milliseconds duration) {
    // Short steps, so that stop() is honoured promptly.
    const auto until = std::chrono::steady_clock::now() + duration;
    while (!stopping_ && std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
            Millis(50), until - std::chrono::steady_clock::now()));
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

bool WorkerLoop::reregister(uint64_t seen, bool& announced) {
    try {
        if (register_again(seen))
            log("registered again with " + std::to_string(options_.threads) + " threads");
        return true;
    } catch (const std::exception& e) {
        if (!announced) log(std::string("cannot register, retrying: ") + e.what());
        announced = true;
        return false;
    }
}

void WorkerLoop::run() {
    Backoff wait(options_.backoff_initial, options_.reconnect_max);
    bool announced = false;
    while (!stopping_) {
        try {
            register_again(registrations_);
            log("registered with " + std::to_string(options_.threads) + " threads");
            break;
        } catch (const std::exception& e) {
            // Unreachable, or an answer this worker cannot use: wait and try again.
            if (!announced)
                log(std::string("coordinator unavailable, retrying: ") + e.what());
            announced = true;
            sleep_unless_stopping(wait.next());
        }
    }
    std::vector<std::jthread> threads;
    for (int t = 0; t < std::max(options_.threads, 1); ++t)
        threads.emplace_back([this] { thread_main(); });
    std::jthread keeper([this] { keeper_main(); });
}

void WorkerLoop::thread_main() {
    enable_flush_to_zero();
    // Two kinds of retry, each waiting longer each time: reaching the coordinator, and
    // jobs that fail here or answers the coordinator refuses.
    Backoff unreachable(options_.backoff_initial, options_.reconnect_max);
    Backoff faults(options_.backoff_initial, options_.failure_max);
    bool announced = false;
    while (!stopping_) {
        std::optional<LeaseGrant> grant;
        const uint64_t registrations = registrations_;
        const auto asked = std::chrono::steady_clock::now();
        try {
            grant = link_.lease(session(), options_.lease_wait);
            if (announced) log("coordinator back");
            announced = false;
        } catch (const WorkerUnknown&) {
            // The coordinator restarted without us: register again, with our threads.
            if (!reregister(registrations, announced))
                sleep_unless_stopping(unreachable.next());
            continue;
        } catch (const std::exception& e) {
            // Unreachable, or an answer this worker cannot read: wait and ask again; a
            // worker thread never dies of what the coordinator said.
            if (!announced) log(std::string("cannot get a lease, retrying: ") + e.what());
            announced = true;
            sleep_unless_stopping(unreachable.next());
            continue;
        }
        // A long-poll that ended early with nothing (a coordinator shutting down, a link
        // that does not wait) is not asked again at once, nor sooner each time.
        if (!grant &&
            std::chrono::steady_clock::now() - asked < options_.lease_wait / 2) {
            sleep_unless_stopping(unreachable.next());
            continue;
        }
        unreachable.reset();
        if (!grant) continue;
        {
            std::lock_guard lock(held_mutex_);
            held_.insert(grant->lease_id);
        }
        std::optional<SampleJobResult> result;
        std::string failure;
        bool unreachable_now = false;
        try {
            auto scene = scenes_.get(grant->scene_hash, [&](const std::string& h) {
                return link_.fetch_scene(session(), h);
            });
            result = trace_sample_job(*scene->tracer, grant->geometry, grant->job, 1,
                                      &stopping_);
        } catch (const JobCancelled&) {
            // Stopping: the lease is given back below.
        } catch (const WorkerUnknown&) {
            // The coordinator restarted since this lease: it is gone with our session.
            release(grant->lease_id);
            reregister(registrations, announced);
            continue;
        } catch (const LinkUnavailable& e) {
            log(std::string("lost the coordinator: ") + e.what());
            unreachable_now = true;
        } catch (const std::exception& e) {
            // A scene that does not load here, or tracing that threw: this worker cannot
            // trace the job. Reported below, so that another worker gets it and a job
            // nobody can trace fails its render instead of going round forever.
            failure = *e.what() ? e.what() : "tracing failed";
        } catch (...) {
            failure = "tracing failed with an unknown exception";
        }
        if (result) {
            release(grant->lease_id);  // from here on the result answers for the lease
            try {
                const CompleteOutcome outcome =
                    link_.complete(session(), grant->lease_id, *result);
                if (outcome.status == CompleteStatus::Merged) {
                    samples_traced_ += result->total_samples();
                    ++jobs_done_;
                    faults.reset();
                } else if (outcome.status == CompleteStatus::Rejected) {
                    const Millis wait = faults.next();
                    log("result rejected: " + outcome.message + "; next lease in " +
                        seconds_text(wait));
                    sleep_unless_stopping(wait);
                }
            } catch (const WorkerUnknown&) {
                // The coordinator restarted since this lease; the job is traced again.
                reregister(registrations, announced);
            } catch (const LinkUnavailable& e) {
                log(std::string("lost the coordinator: ") + e.what());
                sleep_unless_stopping(unreachable.next());
            } catch (const std::exception& e) {
                const Millis wait = faults.next();
                log(std::string("cannot return a result: ") + e.what() +
                    "; next lease in " + seconds_text(wait));
                sleep_unless_stopping(wait);
            }
            continue;
        }
        // Still held: not traced to the end. Reported or given back outside the lock
        // (an RPC).
        if (!release(grant->lease_id)) continue;
        if (!failure.empty()) {
            ++jobs_failed_;
            const Millis wait = faults.next();
            log("cannot trace a job of " + grant->render_id + ": " + failure +
                "; reported, next lease in " + seconds_text(wait));
            try {
                link_.fail(session(), grant->lease_id, failure);
            } catch (const std::exception&) {
                // The lease expires on its own and the job goes to someone else.
            }
            sleep_unless_stopping(wait);
            continue;
        }
        try {
            link_.abandon(session(), grant->lease_id);
        } catch (const std::exception&) {
            // The lease expires on its own.
        }
        if (unreachable_now) sleep_unless_stopping(unreachable.next());
    }
}

void WorkerLoop::keeper_main() {
    while (!stopping_) {
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
