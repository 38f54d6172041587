#include "worker_loop.h"

#include <cstdio>
#include <thread>
#include <vector>

#include "trace_job.h"

namespace aliquot {

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
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

void WorkerLoop::backoff(std::chrono::milliseconds& delay) {
    sleep_unless_stopping(delay);
    delay = std::min(delay * 2, std::chrono::milliseconds(5000));
}

bool WorkerLoop::release(uint64_t lease_id) {
    std::lock_guard lock(held_mutex_);
    return held_.erase(lease_id) > 0;
}

void WorkerLoop::run() {
    std::chrono::milliseconds delay(200);
    bool announced = false;
    while (!stopping_) {
        try {
            lease_ms_ = link_.register_worker(options_.name, uint32_t(options_.threads));
            log("registered with " + std::to_string(options_.threads) + " threads");
            break;
        } catch (const LinkUnavailable& e) {
            if (!announced)
                log(std::string("coordinator unavailable, retrying: ") + e.what());
            announced = true;
            backoff(delay);
        }
    }
    std::vector<std::jthread> threads;
    for (int t = 0; t < std::max(options_.threads, 1); ++t)
        threads.emplace_back([this] { thread_main(); });
    std::jthread keeper([this] { keeper_main(); });
}

void WorkerLoop::thread_main() {
    enable_flush_to_zero();
    std::chrono::milliseconds delay(200);
    bool announced = false;
    while (!stopping_) {
        std::optional<LeaseGrant> grant;
        try {
            grant = link_.lease(options_.name, options_.lease_wait);
            delay = std::chrono::milliseconds(200);
            if (announced) log("coordinator back");
            announced = false;
        } catch (const std::exception& e) {
            // Unreachable, or an answer this worker cannot read: wait and ask again; a
            // worker thread never dies of what the coordinator said.
            if (!announced) log(std::string("cannot get a lease, retrying: ") + e.what());
            announced = true;
            backoff(delay);
            continue;
        }
        if (!grant) continue;
        {
            std::lock_guard lock(held_mutex_);
            held_.insert(grant->lease_id);
        }
        try {
            auto scene = scenes_.get(grant->scene_hash, [&](const std::string& h) {
                return link_.fetch_scene(h);
            });
            const SampleJobResult result = trace_sample_job(
                *scene->tracer, grant->geometry, grant->job, 1, &stopping_);
            release(grant->lease_id);  // from here on the result answers for the lease
            const CompleteOutcome outcome =
                link_.complete(options_.name, grant->lease_id, result);
            if (outcome.status == CompleteStatus::Merged) {
                samples_traced_ += result.total_samples();
                ++jobs_done_;
            } else if (outcome.status == CompleteStatus::Rejected) {
                log("result rejected: " + outcome.message);
            }
        } catch (const JobCancelled&) {
            // Stopping: the lease is given back below.
        } catch (const LinkUnavailable& e) {
            log(std::string("lost the coordinator: ") + e.what());
        } catch (const std::exception& e) {
            // A scene that does not load or a job that does not fit: give the lease back
            // so the render is not stuck on it, and report why.
            log(std::string("cannot trace lease: ") + e.what());
        }
        // Still held: not traced to the end. Given back outside the lock (an RPC).
        if (release(grant->lease_id)) {
            try {
                link_.abandon(options_.name, grant->lease_id);
            } catch (const std::exception&) {
                // The lease expires on its own.
            }
        }
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
                link_.renew(options_.name, lease);
            } catch (const std::exception&) {
                break;  // unreachable: the next period tries again, or the leases expire
            }
        }
    }
}

}  // namespace aliquot
