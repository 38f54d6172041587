// HealthFile: the file's time is the moment the worker was last known alive, not the
// moment it was written, and the file goes when the worker does.
#include "health_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>

namespace aliquot {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono;

fs::path test_path() {
    return fs::temp_directory_path() /
           ("aliquot-health-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
}

system_clock::time_point modified(const fs::path& p) {
    struct stat st {};
    EXPECT_EQ(::stat(p.c_str(), &st), 0);
    return system_clock::time_point(duration_cast<system_clock::duration>(
        seconds(st.st_mtim.tv_sec) + nanoseconds(st.st_mtim.tv_nsec)));
}

TEST(HealthFile, ItsTimeIsWhenTheWorkerWasLastAliveNotWhenItWasWritten) {
    const fs::path path = test_path();
    // A worker whose stalest thread last beat an hour ago.
    const auto before = system_clock::now();
    {
        HealthFile file(
            path, [] { return steady_clock::now() - hours(1); }, hours(1));
        const auto after = system_clock::now();
        ASSERT_TRUE(fs::exists(path));
        EXPECT_GE(modified(path), before - hours(1) - milliseconds(1));
        EXPECT_LE(modified(path), after - hours(1) + milliseconds(1));
        EXPECT_LT(modified(path), before - minutes(59));
    }
    EXPECT_FALSE(fs::exists(path));  // gone with the worker
}

TEST(HealthFile, AFileRemovedMeanwhileIsMadeAgain) {
    const fs::path path = test_path();
    HealthFile file(
        path, [] { return steady_clock::now(); }, hours(1));
    fs::remove(path);
    EXPECT_TRUE(file.stamp());
    EXPECT_TRUE(fs::exists(path));
}

TEST(HealthFile, AFileThatCannotBeMadeIsRefusedAtOnce) {
    EXPECT_THROW(HealthFile(test_path() / "no-such-directory" / "health",
                            [] { return steady_clock::now(); }),
                 std::runtime_error);
}

}  // namespace
}  // namespace aliquot
