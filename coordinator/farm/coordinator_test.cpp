// The Coordinator held against an unlucky operator and a confused worker: nothing they do
// may end the process or overwrite a finished render.
#include "coordinator.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "scene_loader.h"

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

    static RenderSpec small_spec() {
        RenderSpec spec;
        spec.scene_name = "cornell-box";
        spec.scene_json = self_contained_scene_json("cornell-box");
        spec.width = spec.height = 4;
        spec.strategy.method = "uniform";
        spec.strategy.spp = 1;
        return spec;
    }
    static std::string read(const fs::path& p) {
        std::ostringstream s;
        s << std::ifstream(p, std::ios::binary).rdbuf();
        return s.str();
    }

    fs::path dir;
    CoordinatorOptions options;
};

// Issue 12, reproduction 1: a Lease from a worker that never registered here made an
// in-memory worker with no store row; once it was lost, marking it threw on the ticker.
TEST_F(CoordinatorTest, AWorkerThatNeverRegisteredCanBeLostWithoutAnError) {
    Coordinator c(options);
    EXPECT_FALSE(c.lease("ghost", std::chrono::milliseconds(0)).has_value());
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
    EXPECT_NO_THROW(c.tick());
    const std::vector<WorkerStatus> workers = c.workers();
    ASSERT_EQ(workers.size(), 1u);
    EXPECT_EQ(workers[0].name, "ghost");
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

// Issue 12, item 5: a job no worker can trace went round forever at 0 samples. Now it
// fails the render with the reason, in memory and in the store.
TEST_F(CoordinatorTest, AJobNoWorkerCanTraceFailsTheRenderWithTheReason) {
    options.worker_lost_after = std::chrono::seconds(60);  // all three stay alive
    std::string id;
    {
        Coordinator c(options);
        for (const char* w : {"a", "b", "c"}) c.register_worker(w, 1);
        id = c.submit(small_spec());  // one job
        for (const char* w : {"a", "b", "c"}) {
            const auto grant = c.lease(w, std::chrono::milliseconds(0));
            ASSERT_TRUE(grant) << w;
            // The worker it failed on gets nothing while another could take the job.
            if (std::string(w) == "a") {
                EXPECT_TRUE(c.fail(w, grant->lease_id, "cannot open mesh.obj"));
                EXPECT_FALSE(c.lease("a", std::chrono::milliseconds(0)));
            } else {
                EXPECT_FALSE(c.fail("intruder", grant->lease_id, "not mine"));
                EXPECT_TRUE(c.fail(w, grant->lease_id, "cannot open mesh.obj"));
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
    c.register_worker("only", 1);
    const std::string id = c.submit(small_spec());
    for (int i = 0; i < 2; ++i) {
        const auto grant = c.lease("only", std::chrono::milliseconds(0));
        ASSERT_TRUE(grant) << i;
        ASSERT_TRUE(c.fail("only", grant->lease_id, "boom"));
    }
    EXPECT_EQ(c.info(id)->state, RenderState::Failed);
    EXPECT_EQ(c.info(id)->error, "job 0,0 4x4 failed 2 times on 1 worker: boom");
}

// A lease that ends, whatever the way, leaves nothing behind in the coordinator.
TEST_F(CoordinatorTest, LeasesAreForgottenWhenTheyEnd) {
    options.lease_time = std::chrono::milliseconds(30);
    Coordinator c(options);
    c.register_worker("w", 1);
    const std::string first = c.submit(small_spec());
    ASSERT_TRUE(c.lease("w", std::chrono::milliseconds(0)));
    EXPECT_EQ(c.leases_out(), 1u);
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
    c.tick();  // expired
    EXPECT_EQ(c.leases_out(), 0u);

    ASSERT_TRUE(c.lease("w", std::chrono::milliseconds(0)));
    EXPECT_EQ(c.leases_out(), 1u);
    c.cancel(first);
    c.tick();  // its render was cancelled
    EXPECT_EQ(c.leases_out(), 0u);
}

// Issue 12, item 9: after a restart the coordinator did not know its workers, which never
// registered again and showed 0 threads.
TEST_F(CoordinatorTest, KnowsOnlyWorkersThatRegisteredWithIt) {
    {
        Coordinator c(options);
        EXPECT_FALSE(c.lease("w", std::chrono::milliseconds(0)));
        EXPECT_FALSE(c.knows_worker("w"));  // heard from, but never registered here
        c.register_worker("w", 4);
        EXPECT_TRUE(c.knows_worker("w"));
    }
    Coordinator restarted(options);
    EXPECT_FALSE(restarted.knows_worker("w"));
}

}  // namespace
}  // namespace aliquot
