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

}  // namespace
}  // namespace aliquot
