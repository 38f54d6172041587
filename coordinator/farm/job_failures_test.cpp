#include "job_failures.h"

#include <gtest/gtest.h>

namespace aliquot {
namespace {

const PixelRect kRect{8, 16, 4, 2};

TEST(JobFailures, AJobFailsItsRenderOnMaxJobFailuresDistinctWorkers) {
    JobFailures failures;
    JobFailures::OfJob job;
    const FailurePolicy policy;  // 3 workers
    const std::set<std::string> alive{"a", "b", "c", "d"};
    EXPECT_EQ(failures.count(job, kRect, "a", "x", alive, policy), "");
    EXPECT_EQ(failures.count(job, kRect, "a", "x", alive, policy), "");  // same worker
    EXPECT_EQ(failures.count(job, kRect, "b", "x", alive, policy), "");
    EXPECT_EQ(failures.count(job, kRect, "c", "out of\nmemory", alive, policy),
              "job 8,16 4x2 failed 4 times on 3 workers: out of memory");
}

TEST(JobFailures, AJobAWorkerFailedOnWaitsForAnotherThatMayTakeIt) {
    JobFailures failures;
    JobFailures::OfJob job;
    const FailurePolicy policy;
    failures.count(job, kRect, "a", "x", {"a", "b"}, policy);
    EXPECT_FALSE(failures.may_take(job, "a", {"a", "b"}, policy));
    EXPECT_TRUE(failures.may_take(job, "b", {"a", "b"}, policy));
    EXPECT_TRUE(failures.may_take(job, "a", {"a"}, policy));  // no one else to take it
}

TEST(JobFailures, AWorkerThatKeepsFailingIsKeptOffWhileAnotherCanTrace) {
    JobFailures failures;
    JobFailures::OfJob one, two;
    const FailurePolicy policy;  // blocklisted after 2
    failures.count(one, kRect, "a", "x", {"a", "b"}, policy);
    EXPECT_FALSE(failures.kept_off("a", {"a", "b"}, policy));
    failures.count(two, kRect, "a", "x", {"a", "b"}, policy);
    EXPECT_EQ(failures.of("a"), 2u);
    EXPECT_TRUE(failures.kept_off("a", {"a", "b"}, policy));
    EXPECT_FALSE(failures.kept_off("a", {"a"}, policy));  // the only one left
}

}  // namespace
}  // namespace aliquot
