// The Coordinator held against an unlucky operator and a confused worker: nothing they do
// may end the process or overwrite a finished render.
#include "coordinator.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "farm_test_results.h"
#include "scene_loader.h"
#include "store.h"

namespace aliquot {
namespace {

namespace fs = std::filesystem;

class CoordinatorTest : public ::testing::Test {
protected:
    CoordinatorTest()
        : dir(fs::temp_directory_path() /
              ("aliquot_coordinator_test_" + std::to_string(getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
        fs::remove_all(dir);
        options.data_dir = dir;
        options.worker_lost_after = std::chrono::milliseconds(20);
    }
    ~CoordinatorTest() override { fs::remove_all(dir); }

    static RenderSpec small_spec() { return small_test_spec(); }
    static std::string read(const fs::path& p) {
        std::ostringstream s;
        s << std::ifstream(p, std::ios::binary).rdbuf();
        return s.str();
    }

    fs::path dir;
    CoordinatorOptions options;
};

// What the metrics read: samples merged only grow, and renders are counted by state in
// memory and, with a data directory, as the run record has them.
TEST_F(CoordinatorTest, CountsSamplesMergedAndRendersByState) {
    for (const bool with_store : {false, true}) {
        CoordinatorOptions o = options;
        if (!with_store) o.data_dir.clear();
        Coordinator c(o);
        EXPECT_EQ(c.samples_merged(), 0u);
        EXPECT_TRUE(c.render_counts().empty());
        const std::string first = c.submit(small_spec());
        c.submit(small_spec());
        // No job leased yet: both wait in the queue, in memory as in the record.
        const std::map<RenderState, uint64_t> queued = {{RenderState::Queued, 2}};
        for (int i = 0; i < 300 && c.render_counts() != queued; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        EXPECT_EQ(c.render_counts(), queued) << (with_store ? "store" : "memory");
        c.cancel(first);
        const std::string session = c.register_worker("w", 1).session;
        uint64_t traced = 0;
        while (auto grant = c.lease(session, std::chrono::milliseconds(0))) {
            const SampleJobResult result = zero_result(*grant);
            ASSERT_EQ(c.complete(session, grant->lease_id, result).status,
                      CompleteStatus::Merged);
            traced += result.total_samples();
        }
        EXPECT_EQ(traced, 16u);  // the second render: 4x4 pixels at 1 spp
        EXPECT_EQ(c.samples_merged(), traced);
        const std::map<RenderState, uint64_t> want = {{RenderState::Cancelled, 1},
                                                      {RenderState::Done, 1}};
        // The record is written by the backlog's thread: wait for it to catch up.
        for (int i = 0; i < 300 && c.render_counts() != want; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        EXPECT_EQ(c.render_counts(), want) << (with_store ? "store" : "memory");
        EXPECT_EQ(c.store_write_failures(), 0u);
        c.stop();
        fs::remove_all(dir);
    }
}

// The live workers' threads are what a round is cut for: with 32 of them the render's one
// round is cut into at least 64 jobs (round_cutter.h), where one thread gets 28.
TEST_F(CoordinatorTest, ARoundIsCutForTheLiveWorkersCores) {
    for (const uint32_t threads : {1u, 32u}) {
        CoordinatorOptions o = options;
        o.data_dir.clear();
        Coordinator c(o);
        const std::string session = c.register_worker("w", threads).session;
        RenderSpec spec = small_spec();
        spec.width = spec.height = 256;
        spec.strategy.spp = 8;  // one round
        c.submit(spec);
        size_t jobs = 0;
        while (auto grant = c.lease(session, std::chrono::milliseconds(0))) {
            ASSERT_EQ(c.complete(session, grant->lease_id, zero_result(*grant)).status,
                      CompleteStatus::Merged);
            ++jobs;
        }
        if (threads == 1)
            EXPECT_EQ(jobs, 28u);
        else
            EXPECT_GE(jobs, 2u * threads);
        c.stop();
    }
}

// Issue 12, reproduction 1: a Lease from a worker that never registered here made an
// in-memory worker with no store row; once it was lost, marking it threw on the ticker.
// Since issue 13 a call with a session this coordinator never issued is refused with
// WorkerUnknown and leaves no worker behind; a registered worker is lost without error.
TEST_F(CoordinatorTest, AWorkerThatNeverRegisteredIsToldToRegister) {
    Coordinator c(options);
    EXPECT_THROW(c.lease("ghost", std::chrono::milliseconds(0)), WorkerUnknown);
    EXPECT_THROW(c.renew("ghost", 1), WorkerUnknown);
    EXPECT_THROW(c.fetch_scene("ghost", "h"), WorkerUnknown);
    EXPECT_TRUE(c.workers().empty());
    c.register_worker("w", 1);
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
    EXPECT_NO_THROW(c.tick());
    const std::vector<WorkerStatus> workers = c.workers();
    ASSERT_EQ(workers.size(), 1u);
    EXPECT_EQ(workers[0].name, "w");
    EXPECT_EQ(workers[0].state, "lost");
}

// Issue 12, reproduction 4: with aliquot.db moved aside, the next render was r-000001
// again and overwrote that render's files.
TEST_F(CoordinatorTest, RenderIdsAreNotReusedWhenTheDatabaseIsLost) {
    std::string first;
    {
        Coordinator c(options);
        first = c.submit(small_spec());
    }
    const fs::path marker = dir / "renders" / first / "keep.txt";
    std::ofstream(marker) << "an earlier render's file";
    for (const char* f : {"aliquot.db", "aliquot.db-wal", "aliquot.db-shm"})
        fs::remove(dir / f);

    Coordinator c(options);
    const std::string second = c.submit(small_spec());
    EXPECT_NE(second, first);
    EXPECT_EQ(read(marker), "an earlier render's file");
}

TEST_F(CoordinatorTest, AnExistingRenderDirectoryIsSkippedNotReused) {
    fs::create_directories(dir / "renders" / "r-000001");
    Coordinator c(options);
    EXPECT_EQ(c.submit(small_spec()), "r-000002");
}

// Sums for every job the coordinator hands out: a flat grey, no tracing.
SampleJobResult flat_grey(const SampleJob& job, double value = 0.25) {
    SampleJobResult result;
    result.rect = job.rect;
    for (size_t i = 0; i < job.rect.size(); ++i) {
        PixelSums p;
        const uint64_t n = job.counts[i];
        for (int ch = 0; ch < 3; ++ch) p.even[ch] = p.odd[ch] = value * double(n);
        p.sum_sq_luminance = 0.125 * double(n);
        p.samples = n;
        p.rays = 3 * n;
        result.pixels.push_back(p);
    }
    return result;
}

void fake_render(Coordinator& c) {
    const std::string session = c.register_worker("fake", 1).session;
    while (const std::optional<LeaseGrant> grant =
               c.lease(session, std::chrono::milliseconds(0))) {
        SampleJobResult result;
        result.rect = grant->job.rect;
        for (size_t i = 0; i < grant->job.rect.size(); ++i) {
            PixelSums p;
            const uint64_t n = grant->job.counts[i];
            for (int ch = 0; ch < 3; ++ch) p.even[ch] = p.odd[ch] = 0.25 * double(n);
            p.sum_sq_luminance = 0.125 * double(n);
            p.samples = n;
            p.rays = 3 * n;
            result.pixels.push_back(p);
        }
        c.complete(session, grant->lease_id, result);
    }
}

bool wait_for_sessions(Coordinator& c, size_t n) {
    for (int i = 0; i < 500 && c.sessions_in_memory() != n; ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return c.sessions_in_memory() == n;
}

// Issue 12, item 7: finished and cancelled renders stayed in memory with their buffers
// (20 submit-and-cancel cycles at 1024x1024 took the coordinator to 2.1 GB).
TEST_F(CoordinatorTest, AFinishedRenderLeavesMemoryAndIsReadBackFromDisk) {
    Coordinator in_memory(
        CoordinatorOptions{});  // the embedded render: keeps its session
    const std::string kept = in_memory.submit(small_spec());
    fake_render(in_memory);
    const Image expected = *in_memory.image(kept, true);

    Coordinator c(options);
    const std::string done = c.submit(small_spec());
    const std::string cancelled = c.submit(small_spec());
    EXPECT_EQ(c.sessions_in_memory(), 2u);
    EXPECT_EQ(c.memory_in_use(), 2 * render_memory_estimate(4, 4, false));
    c.cancel(cancelled);
    fake_render(c);
    ASSERT_TRUE(wait_for_sessions(c, 0));
    EXPECT_EQ(c.memory_in_use(), 0u);
    EXPECT_EQ(in_memory.sessions_in_memory(), 1u);

    const std::optional<RenderInfo> info = c.info(done);
    ASSERT_TRUE(info);
    EXPECT_EQ(info->state, RenderState::Done);
    EXPECT_EQ(info->samples_done, 16u);
    EXPECT_EQ(info->rays, 48u);
    EXPECT_EQ(info->rounds_done, 1u);
    EXPECT_EQ(info->outcome_json, in_memory.info(kept)->outcome_json);
    const std::optional<Image> image = c.image(done, true);
    ASSERT_TRUE(image);
    EXPECT_EQ(image->rgb, expected.rgb);
    EXPECT_EQ(c.rounds(done)->size(), 1u);
    EXPECT_TRUE(c.buckets(done).has_value());
    EXPECT_EQ(c.info(cancelled)->state, RenderState::Cancelled);
    EXPECT_EQ(c.list(10).size(), 2u);
}

TEST_F(CoordinatorTest, ASubmissionPastTheMemoryBudgetIsRefusedAndChangesNothing) {
    const uint64_t one = render_memory_estimate(4, 4, false);
    options.memory_limit = one + one / 2;
    Coordinator c(options);
    const std::string first = c.submit(small_spec());
    try {
        c.submit(small_spec());
        FAIL() << "a second render fits no budget of 1.5 renders";
    } catch (const MemoryBudgetError& e) {
        EXPECT_EQ(e.needed, one);
        EXPECT_EQ(e.in_use, one);
        EXPECT_EQ(e.limit, options.memory_limit);
        EXPECT_NE(std::string(e.what()).find("--memory-limit"), std::string::npos);
    }
    EXPECT_FALSE(fs::exists(dir / "renders" / "r-000002"));
    EXPECT_EQ(c.list(10).size(), 1u);
    // Once the first has left memory there is room, and the refused one used no id.
    c.cancel(first);
    ASSERT_TRUE(wait_for_sessions(c, 0));
    EXPECT_EQ(c.submit(small_spec()), "r-000002");
}

// Review of issue 34: first-hit sums (their checkpoint copy, the image's layers) and
// `denoised`'s round end were not counted, so a render that fits without them was let
// past the budget with them.
TEST_F(CoordinatorTest, FirstHitSumsAndDenoisingCountAgainstTheMemoryBudget) {
    options.memory_limit = render_memory_estimate(4, 4, false);  // exactly a plain one
    Coordinator c(options);
    RenderSpec with_sums = small_spec();
    with_sums.aux = true;
    EXPECT_THROW(c.submit(with_sums), MemoryBudgetError);
    const std::string plain = c.submit(small_spec());
    c.cancel(plain);
    ASSERT_TRUE(wait_for_sessions(c, 0));

    // `denoised` keeps the sums whatever the spec says, and denoises at each round end.
    CoordinatorOptions in_memory;
    in_memory.memory_limit = render_memory_estimate(4, 4, false, true, false);
    Coordinator d(in_memory);
    RenderSpec denoised = small_spec();
    denoised.strategy.method = "denoised";
    EXPECT_THROW(d.submit(denoised), MemoryBudgetError);
    EXPECT_EQ(d.memory_in_use(), 0u);
}

// Issue 12, item 5: a job no worker can trace went round forever at 0 samples. Now it
// fails the render with the reason, in memory and in the store.
TEST_F(CoordinatorTest, AJobNoWorkerCanTraceFailsTheRenderWithTheReason) {
    options.worker_lost_after = std::chrono::seconds(60);  // all three stay alive
    std::string id;
    {
        Coordinator c(options);
        std::map<std::string, std::string> session;
        for (const char* w : {"a", "b", "c"})
            session[w] = c.register_worker(w, 1).session;
        const std::string intruder = c.register_worker("intruder", 1).session;
        id = c.submit(small_spec());  // one job
        for (const char* w : {"a", "b", "c"}) {
            const auto grant = c.lease(session[w], std::chrono::milliseconds(0));
            ASSERT_TRUE(grant) << w;
            // The worker it failed on gets nothing while another could take the job.
            if (std::string(w) == "a") {
                EXPECT_TRUE(c.fail(session[w], grant->lease_id, "cannot open mesh.obj"));
                EXPECT_FALSE(c.lease(session["a"], std::chrono::milliseconds(0)));
            } else {
                EXPECT_FALSE(c.fail(intruder, grant->lease_id, "not mine"));
                EXPECT_TRUE(c.fail(session[w], grant->lease_id, "cannot open mesh.obj"));
            }
        }
        const RenderInfo info = *c.info(id);
        EXPECT_EQ(info.state, RenderState::Failed);
        EXPECT_EQ(info.error, "job 0,0 4x4 failed on 3 workers: cannot open mesh.obj");
        EXPECT_EQ(c.leases_out(), 0u);
    }
    Coordinator again(options);  // what the store kept
    const RenderInfo info = *again.info(id);
    EXPECT_EQ(info.state, RenderState::Failed);
    EXPECT_EQ(info.error, "job 0,0 4x4 failed on 3 workers: cannot open mesh.obj");
}

TEST_F(CoordinatorTest, ALoneWorkerFailsTheRenderInsteadOfRetryingForever) {
    options.failure_policy.max_job_failures = 2;
    Coordinator c(options);
    const std::string only = c.register_worker("only", 1).session;
    const std::string id = c.submit(small_spec());
    for (int i = 0; i < 2; ++i) {
        const auto grant = c.lease(only, std::chrono::milliseconds(0));
        ASSERT_TRUE(grant) << i;
        ASSERT_TRUE(c.fail(only, grant->lease_id, "boom"));
    }
    EXPECT_EQ(c.info(id)->state, RenderState::Failed);
    EXPECT_EQ(c.info(id)->error, "job 0,0 4x4 failed 2 times on 1 worker: boom");
}

// A lease that ends, whatever the way, leaves nothing behind in the coordinator.
TEST_F(CoordinatorTest, LeasesAreForgottenWhenTheyEnd) {
    options.lease_time = std::chrono::milliseconds(30);
    Coordinator c(options);
    const std::string w = c.register_worker("w", 1).session;
    const std::string first = c.submit(small_spec());
    ASSERT_TRUE(c.lease(w, std::chrono::milliseconds(0)));
    EXPECT_EQ(c.leases_out(), 1u);
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
    c.tick();  // expired
    EXPECT_EQ(c.leases_out(), 0u);

    ASSERT_TRUE(c.lease(w, std::chrono::milliseconds(0)));
    EXPECT_EQ(c.leases_out(), 1u);
    c.cancel(first);
    c.tick();  // its render was cancelled
    EXPECT_EQ(c.leases_out(), 0u);
}

// Issue 12, item 9: after a restart the coordinator did not know its workers, which never
// registered again and showed 0 threads.
TEST_F(CoordinatorTest, KnowsOnlyWorkersThatRegisteredWithIt) {
    std::string session;
    {
        Coordinator c(options);
        EXPECT_FALSE(c.knows_worker("w"));
        session = c.register_worker("w", 4).session;
        EXPECT_TRUE(c.knows_worker("w"));
        EXPECT_FALSE(c.lease(session, std::chrono::milliseconds(0)));  // no work
    }
    Coordinator restarted(options);
    EXPECT_FALSE(restarted.knows_worker("w"));
    // Its session means nothing to the restarted coordinator: it must register again.
    EXPECT_THROW(restarted.lease(session, std::chrono::milliseconds(0)), WorkerUnknown);
}

// Issue 13: worker T completed worker V's lease with radiance 100 (merged, V's result
// ignored, the image wrong), or with a wrong rectangle got V's work thrown away. Now a
// lease belongs to the session that leased it: anyone else is refused, nothing changes,
// and the holder's own result merges.
TEST_F(CoordinatorTest, AnotherWorkersCallsOnALeaseAreRefusedAndChangeNothing) {
    options.data_dir.clear();  // in memory: the finished image stays in the session
    options.worker_lost_after = std::chrono::seconds(60);
    Coordinator c(options);
    const std::string v = c.register_worker("V", 1).session;
    const std::string t = c.register_worker("T", 1).session;
    // Registering with V's name gives a session of its own, not V's leases.
    const std::string fake_v = c.register_worker("V", 1).session;
    EXPECT_NE(v, t);
    EXPECT_NE(v, fake_v);
    EXPECT_EQ(v.size(), 32u);
    const std::string id = c.submit(small_spec());  // one job
    const auto grant = c.lease(v, std::chrono::milliseconds(0));
    ASSERT_TRUE(grant);
    for (const std::string& other : {t, fake_v}) {
        const CompleteOutcome bogus =
            c.complete(other, grant->lease_id, flat_grey(grant->job, 100));
        EXPECT_EQ(bogus.status, CompleteStatus::Ignored);
        EXPECT_EQ(bogus.message, "not your lease");
        SampleJobResult wrong = flat_grey(grant->job);
        wrong.rect.x += 1;
        EXPECT_EQ(c.complete(other, grant->lease_id, wrong).status,
                  CompleteStatus::Ignored);
        EXPECT_FALSE(c.renew(other, grant->lease_id));
        EXPECT_FALSE(c.abandon(other, grant->lease_id));
        EXPECT_FALSE(c.fail(other, grant->lease_id, "not mine"));
    }
    EXPECT_EQ(c.leases_out(), 1u);
    EXPECT_EQ(c.info(id)->state, RenderState::Running);
    EXPECT_EQ(c.info(id)->samples_done, 0u);
    EXPECT_FALSE(c.lease(t, std::chrono::milliseconds(0)));  // nothing was re-issued
    EXPECT_TRUE(c.renew(v, grant->lease_id));
    EXPECT_EQ(c.complete(v, grant->lease_id, flat_grey(grant->job)).status,
              CompleteStatus::Merged);
    EXPECT_EQ(c.info(id)->state, RenderState::Done);
    const std::optional<Image> image = c.image(id, false);
    ASSERT_TRUE(image);
    for (float x : image->rgb) EXPECT_FLOAT_EQ(x, 0.5f);  // V's grey, not T's 100
}

// Issue 13: lease ids were the clock << 16, then +1: one seen in ListWorkers told the
// next. Now they are random 64-bit numbers.
TEST_F(CoordinatorTest, LeaseIdsAreNotSequential) {
    Coordinator c(options);
    const std::string w = c.register_worker("w", 1).session;
    RenderSpec spec = small_spec();
    spec.width = spec.height = 64;  // several jobs
    c.submit(spec);
    std::vector<uint64_t> ids;
    while (auto grant = c.lease(w, std::chrono::milliseconds(0)))
        ids.push_back(grant->lease_id);
    ASSERT_GE(ids.size(), 4u);
    std::set<uint64_t> distinct(ids.begin(), ids.end());
    EXPECT_EQ(distinct.size(), ids.size());
    size_t close =
        0;  // neighbours within 2^32 of each other: chance 2^-31 each if random
    for (size_t i = 1; i < ids.size(); ++i) {
        const uint64_t d =
            ids[i] > ids[i - 1] ? ids[i] - ids[i - 1] : ids[i - 1] - ids[i];
        if (d < (uint64_t(1) << 32)) ++close;
    }
    EXPECT_EQ(close, 0u);
}

// Found in review of issue 13: every Register added a session, and every name a worker,
// for ever: anyone with the worker token could grow the coordinator without bound.
TEST_F(CoordinatorTest, WorkerSessionsAreBoundedAndASessionHoldingALeaseIsKept) {
    options.data_dir.clear();
    options.max_worker_sessions = 8;
    Coordinator c(options);
    c.submit(small_spec());
    const std::string holder = c.register_worker("holder", 1).session;
    const auto grant = c.lease(holder, std::chrono::milliseconds(0));
    ASSERT_TRUE(grant);
    for (int i = 0; i < 1000; ++i) c.register_worker("flood-" + std::to_string(i), 1);
    EXPECT_LE(c.worker_sessions(), 8u);
    // The holder's session survived the flood: its result still merges.
    EXPECT_EQ(c.complete(holder, grant->lease_id, zero_result(*grant)).status,
              CompleteStatus::Merged);
}

TEST_F(CoordinatorTest, RegisteringIsRefusedWhenEverySessionHoldsALease) {
    options.data_dir.clear();
    options.max_worker_sessions = 1;
    Coordinator c(options);
    RenderSpec spec = small_spec();
    c.submit(spec);
    const std::string holder = c.register_worker("holder", 1).session;
    ASSERT_TRUE(c.lease(holder, std::chrono::milliseconds(0)));
    EXPECT_THROW(c.register_worker("late", 1), TooManyWorkers);
    EXPECT_FALSE(c.knows_worker("late"));
}

TEST_F(CoordinatorTest, SilentSessionsAndLongLostWorkersAreForgotten) {
    options.forget_workers_after = std::chrono::milliseconds(0);
    Coordinator c(options);
    const std::string session = c.register_worker("gone", 1).session;
    std::this_thread::sleep_for(std::chrono::milliseconds(30));  // past worker_lost_after
    c.tick();                                                    // lost
    c.tick();                                                    // and forgotten
    EXPECT_EQ(c.worker_sessions(), 0u);
    EXPECT_FALSE(c.knows_worker("gone"));
    // It comes back: told to register again, which works.
    EXPECT_THROW(c.lease(session, std::chrono::milliseconds(0)), WorkerUnknown);
    EXPECT_NO_THROW(c.register_worker("gone", 1));
}

// bench/farm_scale's per-round share: only the Complete that ends a round is counted.
TEST_F(CoordinatorTest, CountsTheTimeOfTheCallsThatEndARound) {
    options.data_dir.clear();
    Coordinator c(options);
    RenderSpec spec = small_spec();
    spec.width = spec.height = 64;  // 16 jobs a round: the first 15 end nothing
    c.submit(spec);
    const std::string w = c.register_worker("w", 1).session;
    for (int job = 0; job < 15; ++job) {
        const auto grant = c.lease(w, std::chrono::milliseconds(0));
        ASSERT_TRUE(grant);
        ASSERT_EQ(c.complete(w, grant->lease_id, zero_result(*grant)).status,
                  CompleteStatus::Merged);
    }
    EXPECT_EQ(c.round_end_seconds(), 0.0);
    while (auto grant = c.lease(w, std::chrono::milliseconds(0))) {
        c.complete(w, grant->lease_id, zero_result(*grant));
    }
    EXPECT_GT(c.round_end_seconds(), 0.0);
}

}  // namespace
}  // namespace aliquot

namespace aliquot {
namespace {

// Each render has a lock of its own (coordinator.h, "Locks"): many workers leasing and
// completing across several renders at once, with a client reading every view meanwhile,
// must leave each render's image exactly as one worker alone makes it.
TEST_F(CoordinatorTest, RendersMergeInParallelAndEachEndsAsItWouldAlone) {
    std::vector<RenderSpec> specs;
    for (const char* method : {"uniform", "optimal", "dammertz", "adaptive"}) {
        RenderSpec spec = small_spec();
        spec.width = 40;
        spec.height = 24;
        spec.seed = specs.size() + 1;
        spec.strategy.method = method;
        if (spec.strategy.method == "uniform") {
            spec.strategy.spp = 24;
        } else {
            spec.strategy.spp = 0;
            spec.strategy.budget = 40 * 24 * 24;
        }
        specs.push_back(spec);
    }
    // Leases until every render of `ids` has ended.
    auto run_to_end = [](Coordinator& c, const std::string& worker,
                         const std::vector<std::string>& ids) {
        const std::string session = c.register_worker(worker, 1).session;
        auto running = [&] {
            for (const std::string& id : ids)
                if (!is_terminal(c.info(id)->state)) return true;
            return false;
        };
        while (running())
            if (auto grant = c.lease(session, std::chrono::milliseconds(20)))
                c.complete(session, grant->lease_id, made_up_result(*grant));
    };
    std::vector<Image> alone;
    for (const RenderSpec& spec : specs) {
        CoordinatorOptions in_memory;
        Coordinator c(in_memory);
        const std::string id = c.submit(spec);
        run_to_end(c, "only", {id});
        ASSERT_EQ(c.info(id)->state, RenderState::Done) << spec.strategy.method;
        alone.push_back(*c.image(id, true));
    }

    Coordinator c(options);
    std::vector<std::string> ids;
    for (const RenderSpec& spec : specs) ids.push_back(c.submit(spec));
    std::atomic<bool> done{false};
    std::thread reader([&] {
        while (!done) {
            for (const std::string& id : ids) {
                c.info(id);
                c.rounds(id);
                c.buckets(id);
                c.image(id, false);
            }
            c.list(10);
            c.workers();
            c.tick();
        }
    });
    std::vector<std::thread> workers;
    for (int w = 0; w < 6; ++w)
        workers.emplace_back([&, w] { run_to_end(c, "w" + std::to_string(w), ids); });
    for (std::thread& t : workers) t.join();
    done = true;
    reader.join();
    for (size_t r = 0; r < specs.size(); ++r) {
        ASSERT_EQ(c.info(ids[r])->state, RenderState::Done) << specs[r].strategy.method;
        const Image together = *c.image(ids[r], true);
        EXPECT_EQ(together.rgb, alone[r].rgb) << specs[r].strategy.method;
        ASSERT_EQ(together.extra.size(), alone[r].extra.size());
        for (size_t e = 0; e < together.extra.size(); ++e)
            EXPECT_EQ(together.extra[e].values, alone[r].extra[e].values)
                << specs[r].strategy.method << " " << together.extra[e].name;
    }
    EXPECT_EQ(c.leases_out(), 0u);
}

}  // namespace
}  // namespace aliquot

namespace aliquot {
namespace {

// Issue 16: leases go to the highest priority first, FIFO within one.
TEST_F(CoordinatorTest, AHighPriorityRenderSubmittedBehindTenLowOnesFinishesFirst) {
    Coordinator c(options);
    std::vector<std::string> low;
    for (int i = 0; i < 10; ++i) low.push_back(c.submit(small_spec()));
    RenderSpec urgent = small_spec();
    urgent.priority = 10;
    const std::string high = c.submit(urgent);
    EXPECT_EQ(c.info(high)->priority, 10);
    const std::string session = c.register_worker("w", 1).session;
    std::vector<std::string> finished_order;
    while (auto grant = c.lease(session, std::chrono::milliseconds(0))) {
        c.complete(session, grant->lease_id, zero_result(*grant));
        const std::string& id = grant->render_id;
        if (is_terminal(c.info(id)->state) &&
            std::find(finished_order.begin(), finished_order.end(), id) ==
                finished_order.end())
            finished_order.push_back(id);
    }
    ASSERT_EQ(finished_order.size(), 11u);
    EXPECT_EQ(finished_order.front(), high);
    // The low ones in the order they came.
    EXPECT_EQ(std::vector<std::string>(finished_order.begin() + 1, finished_order.end()),
              low);
}

TEST_F(CoordinatorTest, APriorityChangedWhileRunningDecidesTheNextLease) {
    Coordinator c(options);
    RenderSpec spec = small_spec();
    spec.width = spec.height = 64;  // several jobs a round
    const std::string first = c.submit(spec), second = c.submit(spec);
    const std::string session = c.register_worker("w", 1).session;
    EXPECT_EQ(c.lease(session, std::chrono::milliseconds(0))->render_id, first);
    ASSERT_TRUE(c.set_priority(second, 3));
    EXPECT_EQ(c.info(second)->priority, 3);
    EXPECT_EQ(c.lease(session, std::chrono::milliseconds(0))->render_id, second);
    EXPECT_FALSE(c.set_priority("r-999999", 1));
    c.cancel(first);
    EXPECT_THROW(c.set_priority(first, 1), RenderFinished);
}

TEST_F(CoordinatorTest, DeletingARenderTakesItsFilesRowsAndMemoryButNeverARunningOne) {
    std::string done_id, running_id;
    {
        Coordinator c(options);
        done_id = c.submit(small_spec());
        RenderSpec big = small_spec();
        big.width = big.height = 64;
        running_id = c.submit(big);
        const std::string session = c.register_worker("w", 1).session;
        while (!is_terminal(c.info(done_id)->state)) {
            auto grant = c.lease(session, std::chrono::milliseconds(0));
            ASSERT_TRUE(grant);
            c.complete(session, grant->lease_id, zero_result(*grant));
        }
        EXPECT_EQ(c.remove(running_id), Coordinator::Removal::Unfinished);
        EXPECT_TRUE(c.info(running_id));
        ASSERT_TRUE(fs::exists(dir / "renders" / done_id));
        EXPECT_EQ(c.remove(done_id), Coordinator::Removal::Removed);
        EXPECT_FALSE(c.info(done_id));
        EXPECT_FALSE(c.image(done_id, false));
        EXPECT_FALSE(c.rounds(done_id));
        EXPECT_FALSE(fs::exists(dir / "renders" / done_id));
        EXPECT_EQ(c.remove(done_id), Coordinator::Removal::Unknown);
        EXPECT_EQ(c.remove("../../etc"), Coordinator::Removal::Unknown);
        c.cancel(running_id);
        EXPECT_EQ(c.remove(running_id), Coordinator::Removal::Removed);
    }
    // A restart finds neither, and does not hand their ids out again.
    Coordinator c(options);
    EXPECT_FALSE(c.info(done_id));
    EXPECT_TRUE(c.list(10).empty());
    EXPECT_NE(c.submit(small_spec()), done_id);
}

TEST_F(CoordinatorTest, RendersFinishedLongerAgoThanKeptAreDeleted) {
    options.keep_finished = std::chrono::hours(24);
    Coordinator c(options);
    const std::string id = c.submit(small_spec());
    const std::string running = c.submit(small_spec());
    const std::string session = c.register_worker("w", 1).session;
    while (!is_terminal(c.info(id)->state)) {
        auto grant = c.lease(session, std::chrono::milliseconds(0));
        ASSERT_TRUE(grant);
        c.complete(session, grant->lease_id, zero_result(*grant));
    }
    // Its end is recorded (and it leaves memory) on the backlog's thread.
    while (c.sessions_in_memory() > 1)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    const int64_t now = unix_millis_now();
    EXPECT_EQ(c.remove_expired(now), 0u);  // finished just now
    EXPECT_EQ(c.remove_expired(now + 25 * 3600 * 1000), 1u);
    EXPECT_FALSE(c.info(id));
    EXPECT_TRUE(c.info(running)) << "a running render is never deleted";
}

// Issue 30, item 5: the submitted scenes were never dropped (200 submit, cancel and
// delete cycles of distinct 1 MB scenes took the coordinator from 28 to 261 MB, the
// database empty). A scene is kept while a render in memory uses it, and dropped after.
TEST_F(CoordinatorTest, ScenesLeaveMemoryWithTheLastRenderThatUsesThem) {
    Coordinator c(options);
    const std::string worker = c.register_worker("w", 1).session;
    for (int i = 0; i < 200; ++i) {
        RenderSpec spec = small_spec();
        spec.scene_json += std::string(size_t(i + 1), ' ');  // distinct: its own hash
        const std::string id = c.submit(spec);
        ASSERT_EQ(c.scenes_in_memory(), 1u) << i;
        EXPECT_EQ(c.fetch_scene(worker, scene_hash(spec.scene_json)), spec.scene_json);
        c.cancel(id);
        ASSERT_TRUE(wait_for_sessions(c, 0)) << i;  // its end recorded, it leaves memory
        ASSERT_EQ(c.remove(id), Coordinator::Removal::Removed) << i;
    }
    EXPECT_EQ(c.scenes_in_memory(), 0u);

    // Two renders of one scene: it stays until the second leaves memory, and a worker
    // still tracing a job of the first reads it from the store meanwhile.
    const RenderSpec spec = small_spec();
    const std::string first = c.submit(spec), second = c.submit(spec);
    c.cancel(first);
    ASSERT_TRUE(wait_for_sessions(c, 1));
    EXPECT_EQ(c.scenes_in_memory(), 1u);
    c.cancel(second);
    ASSERT_TRUE(wait_for_sessions(c, 0));
    EXPECT_EQ(c.scenes_in_memory(), 0u);
    EXPECT_EQ(c.fetch_scene(worker, scene_hash(spec.scene_json)), spec.scene_json);

    // In memory only (no store), deleting the render drops its scene.
    CoordinatorOptions in_memory = options;
    in_memory.data_dir.clear();
    Coordinator m(in_memory);
    const std::string id = m.submit(spec);
    m.cancel(id);
    EXPECT_EQ(m.scenes_in_memory(), 1u);
    EXPECT_EQ(m.remove(id), Coordinator::Removal::Removed);
    EXPECT_EQ(m.scenes_in_memory(), 0u);
}

// Issue 30, item 5: 10,000 Registers left 10,001 workers in memory and in the store.
// Workers (names) are bounded as sessions are: registering past the bound forgets the
// longest-silent worker holding no lease, in memory and in the store.
TEST_F(CoordinatorTest, WorkersAreBoundedInMemoryAndInTheStore) {
    options.max_workers = 16;
    options.worker_lost_after = std::chrono::minutes(1);
    {
        Coordinator c(options);
        c.submit(small_spec());
        const std::string holder =
            c.register_worker("holder", 1, "ipv4:10.0.0.1:5").session;
        const auto grant = c.lease(holder, std::chrono::milliseconds(0));
        ASSERT_TRUE(grant);
        for (int i = 0; i < 1000; ++i)
            c.register_worker("flood-" + std::to_string(i), 1, "ipv4:10.0.0.2:6");
        EXPECT_LE(c.workers().size(), 16u);
        EXPECT_TRUE(c.knows_worker("holder"));
        EXPECT_TRUE(c.knows_worker("flood-999"));
        EXPECT_FALSE(c.knows_worker("flood-0"));
        EXPECT_EQ(c.complete(holder, grant->lease_id, zero_result(*grant)).status,
                  CompleteStatus::Merged);
    }  // what waits is written
    RunStore store(dir);
    EXPECT_LE(store.workers().size(), 16u);

    // When every worker holds a lease, a new name is refused and nothing changes.
    options.max_workers = 1;
    Coordinator c(options);
    c.submit(small_spec());
    const std::string holder = c.register_worker("holder", 1, "ipv4:10.0.0.1:5").session;
    ASSERT_TRUE(c.lease(holder, std::chrono::milliseconds(0)));
    EXPECT_THROW(c.register_worker("late", 1, "ipv4:10.0.0.3:7"), TooManyWorkers);
    EXPECT_FALSE(c.knows_worker("late"));
    EXPECT_NO_THROW(c.register_worker("holder", 1, "ipv4:10.0.0.1:8"));  // known name
}

// Issue 30, item 5: a worker forgotten in memory kept its row in the store for ever, and
// so did every worker of an earlier run. Rows silent for forget_workers_after go.
TEST_F(CoordinatorTest, ForgottenWorkersLeaveTheStoreToo) {
    {
        RunStore store(dir);
        store.upsert_worker("earlier-run", 4, unix_millis_now() - 2 * 3600 * 1000);
        store.upsert_worker("recent", 4, unix_millis_now());
    }
    options.forget_workers_after = std::chrono::hours(1);
    {
        Coordinator c(options);
        c.tick();
    }
    {
        RunStore store(dir);
        const std::vector<WorkerRecord> rows = store.workers();
        ASSERT_EQ(rows.size(), 1u);
        EXPECT_EQ(rows[0].name, "recent");
    }
    options.forget_workers_after = std::chrono::milliseconds(0);
    {
        Coordinator c(options);
        c.register_worker("gone", 1);
        std::this_thread::sleep_for(std::chrono::milliseconds(30));  // lost after 20 ms
        c.tick();                                                    // lost
        c.tick();                                                    // and forgotten
        EXPECT_FALSE(c.knows_worker("gone"));
    }
    RunStore store(dir);
    EXPECT_TRUE(store.workers().empty());
}

// Issue 30, item 9: one holder of the worker token registered under three names, leased
// and failed the job three times: "failed on 3 workers", the render dead. Names prove
// nothing; failures count per host the calls came from.
TEST_F(CoordinatorTest, FailuresCountPerHostNotPerName) {
    Coordinator c(options);
    const std::string id = c.submit(small_spec());  // one job
    auto lease_and_fail = [&](const std::string& session) {
        const auto grant = c.lease(session, std::chrono::milliseconds(0));
        ASSERT_TRUE(grant);
        ASSERT_TRUE(c.fail(session, grant->lease_id, "cannot open mesh.obj"));
    };
    // One host, three names, each on a connection of its own (another port).
    for (int round = 0; round < 3; ++round)
        for (const char* name : {"a", "b", "c"})
            lease_and_fail(c.register_worker(
                                name, 1, "ipv4:10.0.0.9:" + std::to_string(40000 + round))
                               .session);
    EXPECT_EQ(c.info(id)->state, RenderState::Running);
    EXPECT_EQ(c.info(id)->error, "");
    // Two more hosts fail it too: three hosts, the operator's bound.
    lease_and_fail(c.register_worker("d", 1, "ipv6:%5B::1%5D:40001").session);
    EXPECT_EQ(c.info(id)->state, RenderState::Running);
    lease_and_fail(c.register_worker("e", 1, "ipv4:10.0.0.10:40002").session);
    EXPECT_EQ(c.info(id)->state, RenderState::Failed);
    EXPECT_EQ(c.info(id)->error,
              "job 0,0 4x4 failed 11 times on 3 workers: cannot open mesh.obj");
}

// ... unless the operator says a farm of fewer hosts may fail a render (a farm on one
// machine, whose workers all call from one host).
TEST_F(CoordinatorTest, OneHostFailsARenderOnlyWhenTheOperatorSaysSo) {
    options.failure_policy.fail_on_fewer_hosts = true;
    Coordinator c(options);
    const std::string id = c.submit(small_spec());
    for (const char* name : {"a", "b", "c"}) {
        const std::string session =
            c.register_worker(name, 1, "ipv4:127.0.0.1:1").session;
        const auto grant = c.lease(session, std::chrono::milliseconds(0));
        ASSERT_TRUE(grant);
        ASSERT_TRUE(c.fail(session, grant->lease_id, "boom"));
    }
    EXPECT_EQ(c.info(id)->state, RenderState::Failed);
    EXPECT_EQ(c.info(id)->error, "job 0,0 4x4 failed 3 times on 1 worker: boom");
}

// Issue 30, item 10: with umask 022 the data directory was 0755 and aliquot.db, the EXRs
// and the checkpoints 0644: any local user could read every scene and image. Now
// directories are 0700 and files 0600 whatever the umask.
TEST_F(CoordinatorTest, TheDataDirectoryIsPrivateWhateverTheUmask) {
    const mode_t before = ::umask(0);  // as permissive as it gets
    Coordinator c(options);
    RenderSpec spec = small_spec();
    // Two rounds of 1024 spp: a render's last round writes no checkpoint (issue 33).
    spec.width = spec.height = 64;
    spec.strategy.spp = 2048;
    spec.reference = Image(64, 64);
    const std::string id = c.submit(spec);
    // Its first checkpoint is due once it has run 20 times what one should take (6.6 ms
    // at 64x64, issue 33): its first job comes back a while after its lease.
    const std::string session = c.register_worker("slow", 1).session;
    const std::optional<LeaseGrant> grant =
        c.lease(session, std::chrono::milliseconds(0));
    ASSERT_TRUE(grant.has_value());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    c.complete(session, grant->lease_id, zero_result(*grant));
    fake_render(c);
    ASSERT_TRUE(wait_for_sessions(c, 0));  // its image written
    ::umask(before);
    EXPECT_TRUE(fs::exists(dir / "renders" / id / "image.exr"));
    EXPECT_TRUE(fs::exists(dir / "renders" / id / "checkpoint.bin"));
    EXPECT_TRUE(fs::exists(dir / "aliquot.db-wal"));
    size_t files = 0;
    const auto mode = [](const fs::path& p) { return fs::status(p).permissions(); };
    EXPECT_EQ(mode(dir), fs::perms::owner_all);
    for (const auto& entry : fs::recursive_directory_iterator(dir)) {
        if (entry.is_directory()) {
            EXPECT_EQ(mode(entry.path()), fs::perms::owner_all) << entry.path();
        } else {
            ++files;
            EXPECT_EQ(mode(entry.path()), fs::perms::owner_read | fs::perms::owner_write)
                << entry.path();
        }
    }
    EXPECT_GE(files, 6u);  // aliquot.db, -wal, -shm, the image, checkpoint, reference
}

// Issue 30, item 11: a submission that failed for want of disk space left its empty
// render directory behind. (The references directory made a file stands for the full
// disk: the reference cannot be written, for root as for a user.)
TEST_F(CoordinatorTest, ASubmissionThatCannotBeWrittenLeavesNoDirectory) {
    Coordinator c(options);
    { std::ofstream(dir / "references") << "not a directory"; }
    RenderSpec spec = small_spec();
    spec.reference = Image(4, 4);
    for (int i = 0; i < 3; ++i) EXPECT_ANY_THROW(c.submit(spec));
    EXPECT_TRUE(fs::is_empty(dir / "renders"));
    EXPECT_EQ(c.sessions_in_memory(), 0u);
    EXPECT_EQ(c.scenes_in_memory(), 0u);
    fs::remove(dir / "references");
    EXPECT_EQ(c.submit(spec), "r-000004");  // the numbers tried are not reused
}

// Issue 30, item 11: DELETE of a render whose end could not be written (a full disk)
// waited 30 s for the whole record to be written, holding an HTTP thread, then failed.
// It now says at once why it cannot be deleted yet.
TEST_F(CoordinatorTest, DeletingARenderTheDiskRefusesAnswersAtOnceWithTheReason) {
    Coordinator c(options);
    const std::string id = c.submit(small_spec());
    fs::remove_all(dir / "renders" / id);
    { std::ofstream(dir / "renders" / id) << "not a directory"; }
    fake_render(c);
    ASSERT_EQ(c.info(id)->state, RenderState::Done);
    // The backlog's thread makes the failing write: wait for it (a generous deadline,
    // not a timing check).
    for (int i = 0; i < 600 && c.storage_warning().empty(); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string warning = c.storage_warning();
    ASSERT_NE(warning, "");
    try {
        c.remove(id);
        ADD_FAILURE() << "removed a render whose end is not written";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(warning), std::string::npos) << e.what();
    }
    EXPECT_TRUE(c.info(id));
}

// Issue 32: a render is queued until its first job is leased, with its place in the order
// lease() serves renders; a priority change reorders the queue, and a restart keeps it.
TEST_F(CoordinatorTest, ARenderIsQueuedUntilItsFirstLeaseInTheOrderLeasesFollow) {
    std::string a, b, c;
    {
        Coordinator coordinator(options);
        a = coordinator.submit(small_spec());
        b = coordinator.submit(small_spec());
        RenderSpec urgent = small_spec();
        urgent.priority = 5;
        c = coordinator.submit(urgent);
        const auto place = [&](const std::string& id) {
            const RenderInfo info = *coordinator.info(id);
            EXPECT_EQ(info.state, RenderState::Queued) << id;
            EXPECT_EQ(info.seconds, 0.0) << id;
            return info.queue_position;
        };
        EXPECT_EQ(place(c), 1u);
        EXPECT_EQ(place(a), 2u);
        EXPECT_EQ(place(b), 3u);
        ASSERT_TRUE(coordinator.set_priority(b, 9));
        EXPECT_EQ(place(b), 1u);
        EXPECT_EQ(place(c), 2u);
        EXPECT_EQ(place(a), 3u);
        // What was 1 is what a worker gets; it runs, and the others move up.
        const std::string session = coordinator.register_worker("w", 1).session;
        EXPECT_EQ(coordinator.lease(session, std::chrono::milliseconds(0))->render_id, b);
        EXPECT_EQ(coordinator.info(b)->state, RenderState::Running);
        EXPECT_EQ(coordinator.info(b)->queue_position, 0u);
        EXPECT_EQ(place(c), 1u);
        EXPECT_EQ(place(a), 2u);
        // Cancelled while queued: out of the queue.
        coordinator.cancel(c);
        EXPECT_EQ(coordinator.info(c)->queue_position, 0u);
        EXPECT_EQ(place(a), 1u);
    }
    Coordinator again(options);
    EXPECT_EQ(again.info(a)->state, RenderState::Queued);
    EXPECT_EQ(again.info(a)->queue_position, 1u);
    EXPECT_EQ(again.info(b)->state, RenderState::Running);
    EXPECT_EQ(again.info(c)->state, RenderState::Cancelled);
}

// Issue 32: a render's events, in order, kept in the store for after a restart; an
// unknown render has none.
TEST_F(CoordinatorTest, ARendersEventsAreServedInOrderAndOutliveTheCoordinator) {
    std::string id;
    const auto kinds = [](const EventPage& page) {
        std::vector<std::string> out;
        for (const RenderEvent& e : page.events)
            out.push_back(std::string(to_string(e.kind)));
        return out;
    };
    const std::vector<std::string> want = {"submitted", "started", "round_ended",
                                           "finished"};
    {
        Coordinator c(options);
        RenderSpec spec = small_spec();
        spec.name = "shot 12, take 3";
        id = c.submit(spec);
        fake_render(c);
        const std::optional<EventPage> page = c.events(id, -1, 100);
        ASSERT_TRUE(page);
        EXPECT_EQ(kinds(*page), want);
        EXPECT_EQ(page->omitted, 0u);
        for (size_t i = 0; i < page->events.size(); ++i)
            EXPECT_EQ(page->events[i].seq, i);
        const LogFields& submitted = page->events.front().fields;
        EXPECT_NE(std::find_if(submitted.begin(), submitted.end(),
                               [](const LogField& f) {
                                   return f.key == "name" && f.value == "shot 12, take 3";
                               }),
                  submitted.end());
        // After a number: only what came after.
        EXPECT_EQ(c.events(id, 2, 100)->events.size(), 1u);
        EXPECT_FALSE(c.events("r-999999", -1, 100));
        EXPECT_FALSE(c.events("../../etc/passwd", -1, 100));
    }
    Coordinator again(options);
    const std::optional<EventPage> page = again.events(id, -1, 100);
    ASSERT_TRUE(page);
    EXPECT_EQ(kinds(*page), want);
    EXPECT_EQ(again.info(id)->name, "shot 12, take 3");
}

// Issue 32: a name is for people; one that could forge a log line or fill a page is
// refused, and the refused render leaves nothing.
TEST_F(CoordinatorTest, ANameWithControlCharactersOrTooLongIsRefused) {
    Coordinator c(options);
    for (const std::string& bad :
         {std::string("a\nb"), std::string("tab\there"), std::string("esc\x1b[31m"),
          std::string("c1\xc2\x85"), std::string("bad utf-8 \xff"),
          std::string(kMaxRenderName + 1, 'n')}) {
        RenderSpec spec = small_spec();
        spec.name = bad;
        EXPECT_THROW(c.submit(spec), std::invalid_argument) << bad.substr(0, 20);
    }
    EXPECT_TRUE(c.list(10).empty());
    RenderSpec spec = small_spec();
    spec.name = std::string(kMaxRenderName - 6, 'n') + " été";  // UTF-8, at the bound
    ASSERT_EQ(spec.name.size(), kMaxRenderName);
    const std::string id = c.submit(spec);
    EXPECT_EQ(c.info(id)->name, spec.name);
    EXPECT_EQ(c.list(10).at(0).name, spec.name);
}

}  // namespace
}  // namespace aliquot
