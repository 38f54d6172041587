#include "child_process.h"

#include <gtest/gtest.h>

namespace aliquot {
namespace {

TEST(ChildProcess, ReturnsTheExitStatus) {
    EXPECT_EQ(run_process({"true"}), 0);
    EXPECT_EQ(run_process({"sh", "-c", "exit 3"}), 3);
}

TEST(ChildProcess, ACommandThatCannotStartIs127) {
    EXPECT_EQ(run_process({"/nonexistent/aliquot-no-such-program"}), 127);
    EXPECT_EQ(run_process({"aliquot-no-such-program-on-path"}), 127);
    EXPECT_EQ(run_process({}), 127);
}

TEST(ChildProcess, ASignalIs128PlusItsNumber) {
    EXPECT_EQ(run_process({"sh", "-c", "kill -9 $$"}), 128 + 9);
}

}  // namespace
}  // namespace aliquot
