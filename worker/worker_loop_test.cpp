// WorkerLoop against a fake coordinator: what it reports when it cannot trace a job, how
// it waits before asking again, that it registers again with a coordinator that forgot
// it, and that it returns a result while it traces the next job.
#include "worker_loop.h"

#include "failing_allocator.h"
#include "scene_loader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <condition_variable>
#include <future>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

namespace aliquot {
namespace {

using Millis = std::chrono::milliseconds;

// A valid scene of 20,000 triangles.
std::string large_scene() {
    static const std::string text = [] {
        std::string t =
            R"({"camera": {"position": [0, 0, 3.9], "target": [0, 0, 0], )"
            R"("up": [0, 1, 0], "fov": 39}, "materials": {"white": {"type": )"
            R"("diffuse", "reflectance": [0.5, 0.5, 0.5]}}, "shapes": [{"type": )"
            R"("mesh", "material": "white", "emission": [1, 1, 1], )"
            R"("positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [)";
        for (int i = 0; i < 20000; ++i) t += i ? ",[0,1,2]" : "[0,1,2]";
        return t + "]}]}";
    }();
    return text;
}

class FakeLink : public WorkerLink {
public:
    // SceneTooLarge: the scene parses, but not within the memory this worker has.
    enum class Mode {
        BrokenScene,
        NothingAtOnce,
        ForgetsWorker,
        TokenRevoked,
        SceneTooLarge
    };
    explicit FakeLink(Mode mode) : mode_(mode) {}

    Registration register_worker(const std::string&, uint32_t threads) override {
        std::lock_guard lock(mutex_);
        // TokenRevoked: the operator rotated the worker token after the first start.
        if (mode_ == Mode::TokenRevoked && !registered_threads.empty())
            throw LinkRefused("coordinator refused this worker: needs the worker token");
        registered_threads.push_back(threads);
        return {"session-" + std::to_string(registered_threads.size()), 30000};
    }
    std::optional<LeaseGrant> lease(const std::string& session, Millis wait) override {
        {
            std::lock_guard lock(mutex_);
            ++leases;
            lease_sessions.insert(session);
            if (mode_ == Mode::BrokenScene || mode_ == Mode::SceneTooLarge) {
                LeaseGrant g;
                g.lease_id = next_lease_++;
                g.render_id = "r-000001";
                g.scene_hash = "h";
                g.geometry = {4, 4, 1};
                g.job.rect = {0, 0, 4, 4};
                g.job.counts.assign(16, 1);
                g.job.first_sample.assign(16, 0);
                return g;
            }
            if (mode_ == Mode::NothingAtOnce) return std::nullopt;
            // ForgetsWorker: a coordinator restarted after the first registration.
            if (registered_threads.size() < 2 || mode_ == Mode::TokenRevoked)
                throw WorkerUnknown("coordinator does not know this worker");
        }
        std::this_thread::sleep_for(wait);  // a long-poll with no work
        return std::nullopt;
    }
    CompleteOutcome complete(const std::string&, uint64_t,
                             const SampleJobResult&) override {
        return {CompleteStatus::Merged, {}};
    }
    std::optional<std::string> fetch_scene(const std::string&,
                                           const std::string&) override {
        if (mode_ == Mode::SceneTooLarge) {
            std::string scene = large_scene();
            // From here until the failure is reported, this thread's allocations past
            // 64 KiB fail: the 20,000 triangles' JSON array is larger.
            testing::allocation_cap = 64 << 10;
            return scene;
        }
        return std::string("{\"camera\": ");  // does not parse on this worker
    }
    bool renew(const std::string&, uint64_t) override { return true; }
    bool abandon(const std::string&, uint64_t lease_id) override {
        std::lock_guard lock(mutex_);
        abandoned.push_back(lease_id);
        return true;
    }
    bool fail(const std::string& worker, uint64_t lease_id,
              const std::string& reason) override {
        testing::allocation_cap = SIZE_MAX;
        std::lock_guard lock(mutex_);
        failures.push_back({worker, lease_id, reason, std::chrono::steady_clock::now()});
        return true;
    }

    struct Failure {
        std::string worker;
        uint64_t lease_id;
        std::string reason;
        std::chrono::steady_clock::time_point when;
    };
    std::mutex mutex_;
    std::vector<uint32_t> registered_threads;
    std::set<std::string> lease_sessions;  // the sessions Lease calls carried
    std::vector<Failure> failures;
    std::vector<uint64_t> abandoned;
    int leases = 0;

private:
    Mode mode_;
    uint64_t next_lease_ = 1;
};

// Runs a loop on `link` for `duration`, then stops it.
void run_for(FakeLink& link, WorkerOptions options, Millis duration) {
    WorkerLoop loop(link, std::move(options));
    std::thread runner([&] { loop.run(); });
    std::this_thread::sleep_for(duration);
    loop.stop();
    runner.join();
}

WorkerOptions options(int threads) {
    WorkerOptions o;
    o.name = "w";
    o.threads = threads;
    o.quiet = true;
    o.lease_wait = Millis(100);
    o.backoff_initial = Millis(100);
    o.reconnect_max = Millis(400);
    o.failure_max = Millis(400);
    return o;
}

// Issue 12, item 5: the worker abandoned and re-leased such a job at once, thousands of
// times a second.
TEST(WorkerLoopTest, ReportsAJobItCannotTraceWithTheReasonAndBacksOff) {
    FakeLink link(FakeLink::Mode::BrokenScene);
    run_for(link, options(1), Millis(1500));
    std::lock_guard lock(link.mutex_);
    // Failed jobs are reported, never abandoned; what is given back is the job leased
    // ahead, not begun: once after each failure (not held through the wait) and once
    // when the worker stops.
    EXPECT_LE(link.abandoned.size(), link.failures.size() + 1);
    for (const FakeLink::Failure& f : link.failures)
        EXPECT_EQ(std::count(link.abandoned.begin(), link.abandoned.end(), f.lease_id),
                  0);
    ASSERT_GE(link.failures.size(), 3u);
    // Waits of at least 50, 100, 200, 200, ... ms: at most about ten in 1.5 s.
    EXPECT_LE(link.failures.size(), 12u);
    for (const FakeLink::Failure& f : link.failures) {
        EXPECT_EQ(f.worker, "session-1");  // the session, not the name
        EXPECT_NE(f.reason.find("scene:h"), std::string::npos) << f.reason;
    }
    EXPECT_NE(link.failures[0].lease_id, link.failures[1].lease_id);
    // The waits grow: the third gap is longer than the first's shortest possible.
    const auto gap = [&](size_t i) {
        return link.failures[i + 1].when - link.failures[i].when;
    };
    EXPECT_GE(gap(0), Millis(45));
    EXPECT_GE(gap(2), Millis(95));
}

// Issue 30, item 7: out of memory in its scene cache, a worker aborted (the half-parsed
// scene's JSON allocated again as it was destroyed) instead of reporting the job.
TEST(WorkerLoopTest, AScenePastItsMemoryFailsTheJobAndTheWorkerGoesOn) {
    FakeLink link(FakeLink::Mode::SceneTooLarge);
    run_for(link, options(1), Millis(600));
    std::lock_guard lock(link.mutex_);
    ASSERT_GE(link.failures.size(), 2u);  // reported, and leased again after the wait
    for (const FakeLink::Failure& f : link.failures) EXPECT_EQ(f.reason, "out of memory");
}

// A coordinator shutting down answers a long-poll at once with nothing: the worker did
// not wait before asking again.
TEST(WorkerLoopTest, AnEmptyAnswerThatCameAtOnceIsNotAskedAgainAtOnce) {
    FakeLink link(FakeLink::Mode::NothingAtOnce);
    run_for(link, options(2), Millis(1000));
    std::lock_guard lock(link.mutex_);
    EXPECT_GE(link.leases, 2);
    EXPECT_LE(link.leases, 2 * 10);
}

// Issue 12, item 9: a restarted coordinator did not know the worker, which never
// registered again and showed 0 threads.
TEST(WorkerLoopTest, RegistersAgainWithItsThreadsWhenTheCoordinatorForgotIt) {
    FakeLink link(FakeLink::Mode::ForgetsWorker);
    run_for(link, options(2), Millis(500));
    std::lock_guard lock(link.mutex_);
    // Once at start, once again for both threads told, not once per thread.
    EXPECT_EQ(link.registered_threads, (std::vector<uint32_t>{2, 2}));
    EXPECT_GE(link.leases, 3);
    // Then it asks with the session the new registration gave it.
    EXPECT_EQ(link.lease_sessions, (std::set<std::string>{"session-1", "session-2"}));
}

// Issue 13: a refused token cannot become good by asking again, so the worker stops by
// itself and says why, instead of retrying for ever.
TEST(WorkerLoopTest, ARefusedTokenEndsTheLoopWithTheReason) {
    FakeLink link(FakeLink::Mode::TokenRevoked);
    WorkerLoop loop(link, options(2));
    auto ended = std::async(std::launch::async, [&] {
        try {
            loop.run();
        } catch (const LinkRefused& e) {
            return std::string(e.what());
        }
        return std::string("no LinkRefused");
    });
    // A guard against hanging, not a timing assertion: the loop ends on its own.
    ASSERT_EQ(ended.wait_for(std::chrono::seconds(30)), std::future_status::ready);
    EXPECT_NE(ended.get().find("worker token"), std::string::npos);
    std::lock_guard lock(link.mutex_);
    EXPECT_EQ(link.registered_threads.size(), 1u);
}

// A coordinator with `jobs` small jobs of the built-in Cornell box to give, one pixel row
// each, that notes the order of what the worker asks.
class JobsLink : public WorkerLink {
public:
    explicit JobsLink(uint64_t jobs) : jobs_(jobs) {}

    Registration register_worker(const std::string&, uint32_t) override {
        return {"session-1", 30000};
    }
    std::optional<LeaseGrant> lease(const std::string&, Millis wait) override {
        {
            std::lock_guard lock(mutex_);
            // A lease that may wait while the worker holds a job it has not returned
            // could wait for the end of the round that job ends.
            if (wait > Millis(0) && granted_ > completed_) ++waited_holding;
            if (granted_ < jobs_) {
                LeaseGrant g;
                g.lease_id = ++granted_;
                g.render_id = "r-000001";
                g.scene_hash = "h";
                g.geometry = {8, 8, 1};
                g.job.rect = {0, uint32_t(g.lease_id % 8), 8, 1};
                g.job.counts.assign(8, 2);
                g.job.first_sample.assign(8, 0);
                return g;
            }
        }
        std::this_thread::sleep_for(std::min(wait, Millis(20)));
        return std::nullopt;
    }
    CompleteOutcome complete(const std::string&, uint64_t lease_id,
                             const SampleJobResult& result) override {
        std::lock_guard lock(mutex_);
        ++completed_;
        completed.push_back(lease_id);
        granted_when_completed.push_back(granted_);
        samples += result.total_samples();
        return {CompleteStatus::Merged, {}};
    }
    std::optional<std::string> fetch_scene(const std::string&,
                                           const std::string&) override {
        return builtin_scene_json("cornell-box");
    }
    bool renew(const std::string&, uint64_t) override { return true; }
    bool abandon(const std::string&, uint64_t lease_id) override {
        std::lock_guard lock(mutex_);
        abandoned.push_back(lease_id);
        return true;
    }
    bool fail(const std::string&, uint64_t, const std::string&) override { return false; }

    bool all_completed() {
        std::lock_guard lock(mutex_);
        return completed_ == jobs_;
    }

    std::mutex mutex_;
    std::vector<uint64_t> completed, granted_when_completed, abandoned;
    uint64_t samples = 0;
    int waited_holding = 0;

private:
    const uint64_t jobs_;
    uint64_t granted_ = 0, completed_ = 0;
};

// Issue 14: a worker's thread traced nothing while its result travelled and merged. Now
// each job's result is returned while the next job, leased ahead, is traced, and no call
// that may wait is made while a job is held.
TEST(WorkerLoopTest, ReturnsEachResultWhileTracingTheNextJob) {
    JobsLink link(12);
    WorkerLoop loop(link, options(1));
    std::thread runner([&] { loop.run(); });
    while (!link.all_completed()) std::this_thread::sleep_for(Millis(5));
    loop.stop();
    runner.join();
    std::lock_guard lock(link.mutex_);
    EXPECT_EQ(link.completed,
              (std::vector<uint64_t>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}));
    EXPECT_EQ(link.samples, 12u * 8 * 2);
    // Job k's result came back after job k + 1 had been leased, except the last.
    for (size_t k = 0; k + 1 < link.completed.size(); ++k)
        EXPECT_GE(link.granted_when_completed[k], link.completed[k] + 1) << k;
    EXPECT_EQ(link.waited_holding, 0);
    EXPECT_TRUE(link.abandoned.empty());
}

// A coordinator whose Lease never answers until told to: what a stuck call looks like
// from the worker (a deadlock inside the worker looks the same to the beats).
class HangingLink : public FakeLink {
public:
    HangingLink() : FakeLink(Mode::NothingAtOnce) {}
    std::optional<LeaseGrant> lease(const std::string&, Millis) override {
        std::unique_lock lock(hang_mutex_);
        ++hanging_;
        changed_.notify_all();
        changed_.wait(lock, [&] { return released_; });
        return std::nullopt;
    }
    void wait_until_hanging() {
        std::unique_lock lock(hang_mutex_);
        changed_.wait(lock, [&] { return hanging_ > 0; });
    }
    void release() {
        std::lock_guard lock(hang_mutex_);
        released_ = true;
        changed_.notify_all();
    }

private:
    std::mutex hang_mutex_;
    std::condition_variable changed_;
    int hanging_ = 0;
    bool released_ = false;
};

// The liveness signal (aliquot worker --health-file): a thread stuck in a call stops the
// worker's stalest beat, although its other threads (the lease keeper) go on; once the
// call returns it moves again.
TEST(WorkerLoopTest, AStuckThreadStopsTheStalestBeat) {
    HangingLink link;
    WorkerLoop loop(link, options(1));
    std::thread runner([&] { loop.run(); });
    link.wait_until_hanging();
    // Until the keeper has beaten since the stuck thread last did, the keeper's is the
    // stalest; from then on the stuck thread's is, and stays.
    auto stuck_at = loop.stalest_beat();
    do {
        stuck_at = loop.stalest_beat();
        std::this_thread::sleep_for(Millis(100));
    } while (loop.stalest_beat() != stuck_at);
    std::this_thread::sleep_for(Millis(300));  // the keeper beats meanwhile
    EXPECT_EQ(loop.stalest_beat(), stuck_at);
    link.release();
    while (loop.stalest_beat() == stuck_at) std::this_thread::sleep_for(Millis(10));
    EXPECT_GT(loop.stalest_beat(), stuck_at);
    loop.stop();
    runner.join();
}

}  // namespace
}  // namespace aliquot
