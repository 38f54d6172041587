#include "record_backlog.h"

#include <gtest/gtest.h>

#include <future>
#include <stdexcept>
#include <vector>

namespace aliquot {
namespace {

using Clock = RecordBacklog::Clock;
using std::chrono::milliseconds;

TEST(RecordBacklog, AWriteThatFailsIsKeptAndRetriedInOrderWithBackoff) {
    RecordBacklog backlog;
    std::vector<int> written;
    bool disk_full = true;
    auto write = [&](int n) {
        return [&, n] {
            if (disk_full) throw std::runtime_error("database or disk is full");
            written.push_back(n);
        };
    };
    const Clock::time_point t0 = Clock::now();
    backlog.submit("round 0", write(0), t0);
    disk_full = false;
    backlog.submit("round 1", write(1), t0);  // waits behind round 0: order is kept
    EXPECT_TRUE(written.empty());
    EXPECT_EQ(backlog.waiting(), 2u);
    EXPECT_NE(backlog.warning().find("database or disk is full"), std::string::npos);

    backlog.retry(t0 +
                  milliseconds(100));  // before the backoff has passed: nothing tried
    EXPECT_TRUE(written.empty());
    backlog.retry(t0 + milliseconds(600));
    EXPECT_EQ(written, (std::vector<int>{0, 1}));
    EXPECT_EQ(backlog.waiting(), 0u);
    EXPECT_TRUE(backlog.warning().empty());
}

TEST(RecordBacklog, TheBackoffDoublesWhileTheDiskStaysFull) {
    RecordBacklog backlog;
    int tries = 0;
    const Clock::time_point t0 = Clock::now();
    backlog.submit(
        "x", [&] { ++tries, throw std::runtime_error("full"); }, t0);
    for (int ms = 0; ms <= 3500; ms += 100) backlog.retry(t0 + milliseconds(ms));
    // Tried at 0, then 0.5 s later, 1 s after that, then 2 s after that: 4 tries by 3.5
    // s.
    EXPECT_EQ(tries, 4);
    EXPECT_EQ(backlog.waiting(), 1u);
}

TEST(RecordBacklog, CountsEveryFailedAttemptAndNeverForgetsThem) {
    RecordBacklog backlog;
    bool disk_full = true;
    const Clock::time_point t0 = Clock::now();
    backlog.submit(
        "x",
        [&] {
            if (disk_full) throw std::runtime_error("full");
        },
        t0);
    EXPECT_EQ(backlog.failures(), 1u);
    backlog.retry(t0 + milliseconds(600));
    EXPECT_EQ(backlog.failures(), 2u);
    disk_full = false;
    backlog.retry(t0 + milliseconds(2000));
    EXPECT_EQ(backlog.waiting(), 0u);
    EXPECT_EQ(backlog.failures(), 2u);  // written at last; the count stays
}

TEST(RecordBacklog, WritesRunAtOnceWhenNothingWaits) {
    RecordBacklog backlog;
    int n = 0;
    backlog.submit("x", [&] { ++n; });
    EXPECT_EQ(n, 1);
    EXPECT_EQ(backlog.waiting(), 0u);
    EXPECT_TRUE(backlog.warning().empty());
}

// Issue 12, reproduction 8: a checkpoint and an EXR were written under the coordinator's
// lock, and every Lease waited for them. With the writer thread, submit() only queues: it
// returns while the write itself is still blocked.
TEST(RecordBacklog, WithAWriterThreadSubmitReturnsWhileTheWriteIsStillRunning) {
    RecordBacklog backlog;
    backlog.start_writer();
    std::promise<void> release;
    std::shared_future<void> released = release.get_future().share();
    std::promise<void> started;
    bool written = false;
    backlog.submit("a slow checkpoint", [&] {
        started.set_value();
        released.wait();
        written = true;
    });
    started.get_future().wait();  // the write runs, on another thread, and is blocked
    EXPECT_FALSE(written);
    EXPECT_EQ(backlog.waiting(), 1u);
    release.set_value();
    EXPECT_TRUE(backlog.wait_idle(std::chrono::seconds(30)));
    EXPECT_TRUE(written);
}

}  // namespace
}  // namespace aliquot
