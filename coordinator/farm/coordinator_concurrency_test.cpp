// The coordinator's locks (issue 33): its own guards the render list only, so a render's
// merge or round end holds up no other render, and many threads leasing, completing,
// abandoning and cancelling at once change no render's bytes. No test here bounds a
// time: the waits are generous and fail on a deadlock only.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <future>
#include <thread>

#include "coordinator.h"
#include "farm_test_results.h"
#include "scene_loader.h"

namespace aliquot {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

class CoordinatorLocks : public ::testing::Test {
protected:
    CoordinatorLocks()
        : dir(fs::temp_directory_path() /
              ("aliquot_coordinator_locks_" + std::to_string(getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
        fs::remove_all(dir);
        options.data_dir = dir;
    }
    ~CoordinatorLocks() override { fs::remove_all(dir); }

    static RenderSpec spec_of(const char* method, uint64_t seed, uint32_t spp) {
        RenderSpec spec;
        spec.scene_name = "cornell-box";
        spec.scene_json = self_contained_scene_json("cornell-box");
        spec.width = 32;
        spec.height = 24;
        spec.seed = seed;
        spec.strategy.method = method;
        if (spec.strategy.method == "uniform") {
            spec.strategy.spp = spp;
        } else {
            spec.strategy.spp = 0;
            spec.strategy.budget = uint64_t(spec.width) * spec.height * spp;
        }
        return spec;
    }

    fs::path dir;
    CoordinatorOptions options;
};

// With one lock for the coordinator and its renders, the worker below would wait for
// the render whose lock is held; it leases, merges and ends the other one meanwhile.
TEST_F(CoordinatorLocks, ARendersHeldLockHoldsUpNoOtherRendersLeaseOrMerge) {
    Coordinator c(options);
    const RenderSpec one_job = small_test_spec();
    const std::string held = c.submit(one_job);  // first in lease order
    const std::string other = c.submit(one_job);
    const std::string session = c.register_worker("w", 1).session;

    std::unique_lock hold = c.hold_render_for_test(held);
    ASSERT_TRUE(hold.owns_lock());
    auto worker = std::async(std::launch::async, [&] {
        const std::optional<LeaseGrant> grant = c.lease(session, milliseconds(0));
        if (!grant) return std::string("no job");
        const CompleteOutcome out =
            c.complete(session, grant->lease_id, made_up_result(*grant));
        return grant->render_id +
               (out.status == CompleteStatus::Merged ? " merged" : " " + out.message);
    });
    const bool finished =
        worker.wait_for(std::chrono::seconds(60)) == std::future_status::ready;
    const RenderState other_state = c.info(other)->state;  // read while held
    hold.unlock();
    ASSERT_TRUE(finished) << "a lease of another render waited for the held render";
    EXPECT_EQ(worker.get(), other + " merged");
    EXPECT_EQ(other_state, RenderState::Done);
}

// Several workers lease, complete, renew and abandon across renders while a client
// cancels two of them and reads everything: each render that ends is the bytes of its
// run with one worker alone.
TEST_F(CoordinatorLocks, ManyThreadsAcrossRendersEndEachAsOneWorkerAloneWould) {
    const std::vector<RenderSpec> finishing = {
        spec_of("uniform", 1, 16), spec_of("optimal", 2, 16), spec_of("adaptive", 3, 16)};
    auto run_alone = [](const std::vector<std::string>& ids, Coordinator& c) {
        const std::string session = c.register_worker("alone", 1).session;
        auto running = [&] {
            for (const std::string& id : ids)
                if (!is_terminal(c.info(id)->state)) return true;
            return false;
        };
        while (running())
            if (auto grant = c.lease(session, milliseconds(20)))
                c.complete(session, grant->lease_id, made_up_result(*grant));
    };
    std::vector<Image> alone;
    for (const RenderSpec& spec : finishing) {
        Coordinator c(CoordinatorOptions{});
        const std::string id = c.submit(spec);
        run_alone({id}, c);
        ASSERT_EQ(c.info(id)->state, RenderState::Done) << spec.strategy.method;
        alone.push_back(*c.image(id, true));
    }

    Coordinator c(options);
    std::vector<std::string> ids, cancelled;
    for (size_t r = 0; r < finishing.size(); ++r) {
        ids.push_back(c.submit(finishing[r]));
        // Renders of thousands of jobs, cancelled while their jobs are out.
        cancelled.push_back(c.submit(spec_of("uniform", 10 + r, 1u << 20)));
    }
    auto running = [&] {
        for (const std::string& id : ids)
            if (!is_terminal(c.info(id)->state)) return true;
        return false;
    };
    std::atomic<bool> done{false};
    std::vector<std::thread> threads;
    for (int w = 0; w < 4; ++w)
        threads.emplace_back([&, w] {
            const std::string session =
                c.register_worker("w" + std::to_string(w), 1).session;
            for (uint64_t n = 0; running(); ++n) {
                const std::optional<LeaseGrant> grant =
                    c.lease(session, milliseconds(20));
                if (!grant) continue;
                if ((n + w) % 7 == 3) {
                    c.abandon(session, grant->lease_id);  // re-issued to anyone
                    continue;
                }
                if (n % 5 == 1) c.renew(session, grant->lease_id);
                c.complete(session, grant->lease_id, made_up_result(*grant));
            }
        });
    threads.emplace_back([&] {
        // Each once a job of it has been leased (queued until then), or the others ended.
        // All watched at once: with made-up results a render of a thousand jobs can end
        // in ~50 ms, and waiting on them one by one let a later one end Done before its
        // turn (2 runs in 30).
        std::vector<std::string> left = cancelled;
        while (!left.empty()) {
            for (auto it = left.begin(); it != left.end();)
                if (c.info(*it)->state != RenderState::Queued || !running()) {
                    c.cancel(*it);
                    it = left.erase(it);
                } else {
                    ++it;
                }
            std::this_thread::sleep_for(milliseconds(1));
        }
    });
    threads.emplace_back([&] {
        while (!done) {
            for (const std::string& id : ids) {
                c.info(id);
                c.rounds(id);
            }
            c.list(10);
            c.workers();
            c.tick();
        }
    });
    for (size_t t = 0; t + 1 < threads.size(); ++t) threads[t].join();
    done = true;
    threads.back().join();

    for (size_t r = 0; r < finishing.size(); ++r) {
        const std::string& method = finishing[r].strategy.method;
        ASSERT_EQ(c.info(ids[r])->state, RenderState::Done) << method;
        const Image together = *c.image(ids[r], true);
        EXPECT_EQ(together.rgb, alone[r].rgb) << method;
        ASSERT_EQ(together.extra.size(), alone[r].extra.size()) << method;
        for (size_t e = 0; e < together.extra.size(); ++e)
            EXPECT_EQ(together.extra[e].values, alone[r].extra[e].values)
                << method << " " << together.extra[e].name;
    }
    for (const std::string& id : cancelled)
        EXPECT_EQ(c.info(id)->state, RenderState::Cancelled) << id;
    EXPECT_EQ(c.leases_out(), 0u);
}

// Review of issue 33: a worker was heard from only when its lease poll began, so a poll
// that waited longer than worker_lost_after marked a worker that was waiting on us lost.
TEST_F(CoordinatorLocks, AWorkerWaitingInALeasePollIsNotLost) {
    options.worker_lost_after = milliseconds(100);
    Coordinator c(options);
    std::atomic<bool> polling{true};
    std::thread worker([&] {
        // Registered and polling in one go; with no render, the poll waits it all.
        const std::string session = c.register_worker("w", 1).session;
        c.lease(session, milliseconds(600));
        polling = false;
    });
    int ticks = 0, lost = 0;
    while (polling) {
        c.tick();
        const std::vector<WorkerStatus> workers = c.workers();
        if (!workers.empty()) {
            ++ticks;
            if (workers[0].state == "lost") ++lost;
        }
        std::this_thread::sleep_for(milliseconds(5));
    }
    worker.join();
    c.tick();
    EXPECT_GT(ticks, 0);
    EXPECT_EQ(lost, 0) << "of " << ticks << " ticks during the poll";
    EXPECT_EQ(c.workers().at(0).state, "idle");  // heard from at the poll's end
}

}  // namespace
}  // namespace aliquot
