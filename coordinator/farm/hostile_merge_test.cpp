// Issue 33 review: merges added off the render's lock meet leases that expire, results
// refused after their lease ended, abandons and readers, and still add each job once.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <future>
#include <limits>
#include <mutex>
#include <new>
#include <random>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "coordinator.h"
#include "farm_test_results.h"
#include "render_session.h"
#include "scene_loader.h"

// failing_allocator.h's cap on this thread's allocations (its operator new is
// submit_memory_test.cpp's, one file of this binary): declared again as it is there.
namespace aliquot::testing {
inline thread_local size_t allocation_cap = SIZE_MAX;
}  // namespace aliquot::testing

namespace aliquot {
namespace {

using std::chrono::milliseconds;

void expect_same_image(const Image& a, const Image& b, const std::string& what) {
    EXPECT_EQ(a.rgb, b.rgb) << what;
    ASSERT_EQ(a.extra.size(), b.extra.size()) << what;
    for (size_t e = 0; e < a.extra.size(); ++e)
        EXPECT_EQ(a.extra[e].values, b.extra[e].values) << what << " " << a.extra[e].name;
}

// What a session's merges are handed: a worker's result for `job`, made from it alone.
SampleJobResult result_for(const SampleJob& job) {
    LeaseGrant grant;
    grant.job = job;
    return made_up_result(grant);
}

bool overlap(const PixelRect& a, const PixelRect& b) {
    return a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height &&
           b.y < a.y + a.height;
}

// The next job `s` issues under lease ++lease: it waits (no time is asserted)
// through a plan being made, and is nullopt only once the render has ended.
std::optional<SampleJob> next_job(RenderSession& s, uint64_t& lease) {
    const auto far = RenderSession::Clock::now() + std::chrono::hours(1);
    // A bound only so that a session that never issues again fails rather than hangs.
    for (int tries = 0; tries < 10000 && !s.finished(); ++tries) {
        if (std::optional<SampleJob> job = s.issue(++lease, "w", far)) return job;
        std::this_thread::sleep_for(milliseconds(1));
    }
    return std::nullopt;
}

// Merges every job `s` issues, to its end: what one worker alone does.
void merge_to_the_end(RenderSession& s, uint64_t& lease) {
    while (const std::optional<SampleJob> job = next_job(s, lease))
        EXPECT_NE(s.complete(lease, "w", result_for(*job)).status,
                  CompleteStatus::Ignored);
    EXPECT_EQ(s.state(), RenderState::Done) << s.error();
}

// A result of the round out refused by its add (off the render's lock) leaves its job
// unmerged, and in no queue until its end_merge, under the lock again, puts it back. A
// job of the round ahead cut in between over its pixels counts its samples as to come
// (unmerged_jobs), so it starts its pixels' samples after them, and the job traced again
// does not trace them twice.
TEST(HostileMerges, AJobOfTheRoundAheadCutBeforeARefusalIsCountedStartsAfterItsSamples) {
    const RenderSpec spec = square_test_spec("uniform", 64, 2048);  // two rounds of 1024
    RenderSession s("r", spec, 0);
    s.start();
    uint64_t lease = 0;
    const std::optional<SampleJob> out = next_job(s, lease);
    ASSERT_TRUE(out);
    const uint64_t out_lease = lease;
    SampleJobResult unlike = result_for(*out);
    unlike.pixels[0].samples += 1;  // unlike its job: its add refuses it
    RenderSession::Merge refused = s.begin_merge(out_lease, "w", unlike, nullptr);
    ASSERT_FALSE(refused.outcome);
    s.add_merge(refused, unlike);
    ASSERT_FALSE(refused.added);
    // Before its end_merge: the rest of the round out, then the round ahead up to a job
    // over the refused one's pixels.
    std::optional<SampleJob> over;
    while (!over) {
        std::optional<SampleJob> job = next_job(s, lease);
        ASSERT_TRUE(job);
        if (overlap(job->rect, out->rect))
            over = std::move(job);
        else
            EXPECT_EQ(s.complete(lease, "w", result_for(*job)).status,
                      CompleteStatus::Merged);
    }
    const uint64_t over_lease = lease;
    for (uint32_t y = 0; y < over->rect.height; ++y)
        for (uint32_t x = 0; x < over->rect.width; ++x) {
            const uint32_t px = over->rect.x + x, py = over->rect.y + y;
            if (!overlap({px, py, 1, 1}, out->rect)) continue;
            const size_t o =
                size_t(py - out->rect.y) * out->rect.width + (px - out->rect.x);
            ASSERT_EQ(over->first_sample[size_t(y) * over->rect.width + x],
                      out->first_sample[o] + out->counts[o])
                << "pixel " << px << "," << py
                << ": the refused job's samples are traced twice";
        }
    EXPECT_EQ(s.end_merge(refused).status, CompleteStatus::Rejected);
    EXPECT_EQ(s.complete(over_lease, "w", result_for(*over)).status,
              CompleteStatus::Merged);
    merge_to_the_end(s, lease);
    expect_same_image(s.image(true), rendered_alone(spec), "uniform");
}

// A merge keeps what it needs, its add recorded in flight (a job of the round out) or a
// copy of its result held (the round ahead's), before its lease ends: when that fails
// (std::bad_alloc, thrown here by a test hook) the job is still the render's and is
// issued again at once. Kept after the lease ended, it would be in no queue, and the
// render would wait for it for good.
TEST(HostileMerges, AMergeThatCannotKeepWhatItNeedsGivesItsJobBack) {
    for (const bool ahead : {false, true}) {
        const RenderSpec spec = square_test_spec("uniform", 64, 2048);  // two rounds
        RenderSession s("r", spec, 0);
        s.start();
        bool fail = false;
        s.while_keeping = [&](size_t) {
            if (std::exchange(fail, false)) throw std::bad_alloc();
        };
        uint64_t lease = 0;
        // The round out's first job stays out, so that the round ahead's results are
        // held.
        const std::optional<SampleJob> first = next_job(s, lease);
        ASSERT_TRUE(first);
        const uint64_t first_lease = lease;
        std::optional<SampleJob> job = first;
        uint64_t job_lease = first_lease;
        if (ahead) {
            // The round ahead's jobs start past the round out's samples.
            while ((job = next_job(s, lease)) && job->first_sample[0] == 0)
                EXPECT_EQ(s.complete(lease, "w", result_for(*job)).status,
                          CompleteStatus::Merged);
            ASSERT_TRUE(job);
            job_lease = lease;
        }
        fail = true;
        EXPECT_THROW(s.complete(job_lease, "w", result_for(*job)), std::bad_alloc);
        EXPECT_FALSE(s.holds(job_lease));
        const std::optional<SampleJob> again = next_job(s, lease);
        ASSERT_TRUE(again) << (ahead ? "the round ahead's job" : "the round out's job")
                           << " is lost";
        EXPECT_TRUE(again->rect == job->rect);
        EXPECT_EQ(again->first_sample, job->first_sample);
        EXPECT_EQ(s.complete(lease, "w", result_for(*again)).status,
                  CompleteStatus::Merged);
        if (ahead) {
            EXPECT_EQ(s.complete(first_lease, "w", result_for(*first)).status,
                      CompleteStatus::Merged);
        }
        merge_to_the_end(s, lease);
        expect_same_image(s.image(true), rendered_alone(spec), ahead ? "ahead" : "out");
    }
}

// A result refused by its add (a non-finite sum, found off the render's lock) whose
// failure cannot be counted (no memory) leaves its job queued again: it had no lease
// and no add in flight left, and nothing would have issued it again, so the round never
// ended and the render stayed running for good.
TEST(HostileMerges, ARefusedAddWhoseFailureCannotBeCountedGivesItsJobBack) {
    const RenderSpec spec = square_test_spec("uniform", 64, 4);  // one round
    RenderSession s("r", spec, 0);
    s.start();
    bool fail = true;
    s.while_counting_failure = [&](size_t) {
        if (std::exchange(fail, false)) throw std::bad_alloc();
    };
    uint64_t lease = 0;
    const std::optional<SampleJob> job = next_job(s, lease);
    ASSERT_TRUE(job);
    SampleJobResult poisoned = result_for(*job);
    poisoned.pixels[0].even[0] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(s.complete(lease, "w", poisoned), std::bad_alloc);
    EXPECT_FALSE(s.holds(lease));
    std::optional<SampleJob> again;
    while ((again = next_job(s, lease)) && !(again->rect == job->rect))
        EXPECT_EQ(s.complete(lease, "w", result_for(*again)).status,
                  CompleteStatus::Merged);
    ASSERT_TRUE(again) << "the refused job is lost";
    EXPECT_EQ(again->first_sample, job->first_sample);
    EXPECT_EQ(s.complete(lease, "w", result_for(*again)).status, CompleteStatus::Merged);
    merge_to_the_end(s, lease);
    expect_same_image(s.image(true), rendered_alone(spec), "refused");
}

// Leases the round out's first job and keeps it out, merges the rest of the round out,
// then has `held` results of the round ahead held (merged, not added): the round out's
// end adds them once the first job's result is merged. Returns the first job and lease.
std::pair<SampleJob, uint64_t> hold_round_ahead(RenderSession& s, uint64_t& lease,
                                                size_t held,
                                                SampleJobResult (*made)(const SampleJob&),
                                                std::vector<SampleJob>* jobs = nullptr) {
    std::optional<SampleJob> first = next_job(s, lease);
    EXPECT_TRUE(first);
    const uint64_t first_lease = lease;
    for (size_t n = 0; n < held;) {
        const std::optional<SampleJob> job = next_job(s, lease);
        if (!job) break;
        const bool ahead = job->first_sample[0] != 0;  // past the round out's samples
        EXPECT_EQ(s.complete(lease, "w", ahead ? made(*job) : result_for(*job)).status,
                  CompleteStatus::Merged);
        if (ahead && jobs) jobs->push_back(*job);
        n += ahead;
    }
    return {std::move(*first), first_lease};
}

// A held result of the round ahead whose add fails for want of memory when its round
// comes (std::bad_alloc, thrown here by a test hook) gives its job back, and the held
// results after it still merge. Before, the exception left add_held with the rest of
// them, whose jobs were in no queue, and failed the render ("cannot plan round 2").
TEST(HostileMerges, AHeldResultThatCannotBeAddedGivesItsJobBackAndTheRestMerge) {
    const RenderSpec spec = square_test_spec("uniform", 64, 2048);  // two rounds
    RenderSession s("r", spec, 0);
    s.start();
    bool fail = true;
    s.while_adding_held = [&](size_t) {
        if (std::exchange(fail, false)) throw std::bad_alloc();
    };
    uint64_t lease = 0;
    const auto [first, first_lease] = hold_round_ahead(s, lease, 3, result_for);
    EXPECT_EQ(s.complete(first_lease, "w", result_for(first)).status,
              CompleteStatus::Merged);
    EXPECT_FALSE(fail) << "no held result was added";
    EXPECT_EQ(s.state(), RenderState::Running) << s.error();
    merge_to_the_end(s, lease);
    expect_same_image(s.image(true), rendered_alone(spec), "held");
}

// A round's end that throws after the round has merged (on_round's record, here a test's
// throw; a reference the image cannot be compared with) fails the render with the
// reason, and the merge that ended the round returns. Before, the exception escaped that
// merge, out of the render's own catch, and left the render Running with no job out.
TEST(HostileMerges, ARoundEndThatThrowsFailsItsRenderWithTheReason) {
    for (const bool by_reference : {false, true}) {
        RenderSpec spec = square_test_spec("uniform", 64, 4);  // one round
        if (by_reference) spec.reference = Image(8, 8);        // not the render's size
        RenderSession s("r", spec, 0);
        if (!by_reference)
            s.on_round = [](RenderSession&, const RoundSummary&) {
                throw std::runtime_error("the record cannot be kept");
            };
        s.start();
        uint64_t lease = 0;
        while (const std::optional<SampleJob> job = next_job(s, lease)) {
            CompleteOutcome outcome{CompleteStatus::Ignored, {}};
            EXPECT_NO_THROW(outcome = s.complete(lease, "w", result_for(*job)));
            EXPECT_EQ(outcome.status, CompleteStatus::Merged);
        }
        EXPECT_EQ(s.state(), RenderState::Failed) << by_reference;
        EXPECT_NE(s.error().find(by_reference ? "resolution differs"
                                              : "the record cannot be kept"),
                  std::string::npos)
            << s.error();
        EXPECT_NE(s.error().find("cannot end round"), std::string::npos) << s.error();
    }
}

// A refused result whose failure cannot be counted, whose job cannot be queued again
// either, and whose render's reason cannot be allocated (std::bad_alloc from test hooks,
// then from every allocation) fails its render, "out of memory": the job is in no queue
// and under no lease, so a render left Running would wait for it for good. Before, the
// reason's allocation threw out of end_merge's catch and left the render Running.
TEST(HostileMerges, ARefusalThatCannotBeCountedNorQueuedFailsItsRender) {
    const RenderSpec spec = square_test_spec("uniform", 64, 4);  // one round
    RenderSession s("r", spec, 0);
    s.start();
    s.while_counting_failure = [](size_t) { throw std::bad_alloc(); };
    s.while_requeueing = [](size_t) {
        testing::allocation_cap = 0;  // every allocation fails, on this thread
        throw std::bad_alloc();
    };
    uint64_t lease = 0;
    const std::optional<SampleJob> job = next_job(s, lease);
    ASSERT_TRUE(job);
    SampleJobResult poisoned = result_for(*job);
    poisoned.pixels[0].even[0] = std::numeric_limits<double>::quiet_NaN();
    bool threw = false;
    try {
        s.complete(lease, "w", poisoned);
    } catch (const std::bad_alloc&) {
        threw = true;
    }
    testing::allocation_cap = SIZE_MAX;
    EXPECT_TRUE(threw);
    s.while_requeueing = nullptr;
    EXPECT_EQ(s.state(), RenderState::Failed) << "the refused job is lost";
    EXPECT_EQ(s.error(), "out of memory");
}

// A failure a worker reports that cannot be counted (std::bad_alloc, from a test hook)
// leaves its job queued again, and an abandon that cannot queue its job leaves it under
// its lease (which expires): neither loses it. Before, both ended the lease first.
TEST(HostileMerges, AFailureOrAbandonThatThrowsLosesNoJob) {
    for (const bool abandon : {false, true}) {
        const RenderSpec spec = square_test_spec("uniform", 64, 4);  // one round
        RenderSession s("r", spec, 0);
        s.start();
        bool fail = true;
        const auto once = [&](size_t) {
            if (std::exchange(fail, false)) throw std::bad_alloc();
        };
        (abandon ? s.while_requeueing : s.while_counting_failure) = once;
        uint64_t lease = 0;
        const std::optional<SampleJob> job = next_job(s, lease);
        ASSERT_TRUE(job);
        const uint64_t held = lease;
        if (abandon) {
            EXPECT_THROW(s.abandon(held, "w"), std::bad_alloc);
            EXPECT_TRUE(s.holds(held)) << "the abandoned job is lost";
            EXPECT_TRUE(s.abandon(held, "w"));
        } else {
            EXPECT_THROW(s.fail_job(held, "w", "crashed", {"w"}, {}), std::bad_alloc);
            EXPECT_FALSE(s.holds(held));
        }
        std::optional<SampleJob> again;
        while ((again = next_job(s, lease)) && !(again->rect == job->rect))
            EXPECT_EQ(s.complete(lease, "w", result_for(*again)).status,
                      CompleteStatus::Merged);
        ASSERT_TRUE(again) << "the job is lost";
        EXPECT_EQ(s.complete(lease, "w", result_for(*again)).status,
                  CompleteStatus::Merged);
        merge_to_the_end(s, lease);
        expect_same_image(s.image(true), rendered_alone(spec), "given back");
    }
}

// A lease whose deadline passes while its result is being added (off the render's
// lock) is not expired and issued again: its job's pixels are added once, by its holder.
TEST(HostileMerges, ALeaseExpiringWhileItsResultIsAddedIsNotIssuedAgain) {
    CoordinatorOptions options;
    options.lease_time = milliseconds(1);
    Coordinator c(options);
    const RenderSpec spec = square_test_spec("uniform", 64, 4);  // one round of 16 jobs
    const std::string id = c.submit(spec);
    const std::string a = c.register_worker("a", 8).session;
    const std::string b = c.register_worker("b", 8).session;
    const std::optional<LeaseGrant> ga = c.lease(a, milliseconds(0));
    ASSERT_TRUE(ga);
    HeldAdd held;
    auto merge = merge_held(c, id, a, *ga, held);
    // Past its deadline (sleeping longer only makes sure), and swept.
    std::this_thread::sleep_for(milliseconds(20));
    c.tick();
    uint64_t samples = 0;
    for (const uint32_t n : ga->job.counts) samples += n;
    while (const std::optional<LeaseGrant> gb = c.lease(b, milliseconds(0))) {
        EXPECT_FALSE(gb->job.rect == ga->job.rect) << "a job mid-merge was issued again";
        for (const uint32_t n : gb->job.counts) samples += n;
        EXPECT_EQ(c.complete(b, gb->lease_id, made_up_result(*gb)).status,
                  CompleteStatus::Merged);
    }
    held.release.set_value();
    EXPECT_EQ(merge.get(), CompleteStatus::Merged);
    ASSERT_EQ(c.info(id)->state, RenderState::Done);
    EXPECT_EQ(samples, uint64_t(64) * 64 * 4);
    EXPECT_EQ(c.info(id)->samples_done, samples);
    expect_same_image(*c.image(id, true), rendered_alone(spec), "uniform");
}

// A result of the round ahead is held, and its merge said Merged, before its sums can
// be checked against the buffers; refused when its round comes (here its sums would pass
// 1e30 a sample), it counts for no one, as any refused result: neither the farm's
// merged samples nor its worker's count it, and its job is traced again. Before, both
// counted it when it was held.
TEST(HostileMerges, AHeldResultRefusedWhenItsRoundComesIsNotCountedAsMerged) {
    Coordinator c(CoordinatorOptions{});
    const RenderSpec spec = square_test_spec("uniform", 64, 2048);  // two rounds
    const std::string id = c.submit(spec);
    const std::string a = c.register_worker("a", 8).session;
    const std::string b = c.register_worker("b", 8).session;
    const std::optional<LeaseGrant> ga = c.lease(a, milliseconds(0));
    ASSERT_TRUE(ga);  // kept out: the round ahead's results are held meanwhile
    bool poisoned = false;
    for (int tries = 0; tries < 1000 && !poisoned; ++tries) {
        const std::optional<LeaseGrant> g = c.lease(b, milliseconds(20));
        if (!g) continue;
        SampleJobResult result = made_up_result(*g);
        poisoned = g->job.first_sample[0] != 0;          // the round ahead's
        if (poisoned) result.pixels[0].even[0] = 1e300;  // finite, but not in the sums
        EXPECT_EQ(c.complete(b, g->lease_id, result).status, CompleteStatus::Merged);
    }
    ASSERT_TRUE(poisoned);
    EXPECT_EQ(c.complete(a, ga->lease_id, made_up_result(*ga)).status,
              CompleteStatus::Merged);
    // Both: the refused job waits for a worker it did not fail on.
    for (int tries = 0; tries < 10000 && !is_terminal(c.info(id)->state); ++tries)
        for (const std::string& w : {a, b})
            if (const std::optional<LeaseGrant> g = c.lease(w, milliseconds(20)))
                c.complete(w, g->lease_id, made_up_result(*g));
    ASSERT_EQ(c.info(id)->state, RenderState::Done) << c.info(id)->error;
    const uint64_t samples = c.info(id)->samples_done;
    EXPECT_EQ(samples, uint64_t(64) * 64 * 2048);
    EXPECT_EQ(c.samples_merged(), samples) << "the refused result counted as merged";
    uint64_t traced = 0;
    for (const WorkerStatus& w : c.workers()) traced += w.samples_traced;
    EXPECT_EQ(traced, samples) << "the refused result counted for its worker";
    expect_same_image(*c.image(id, true), rendered_alone(spec), "refused when held");
}

// A job given back by a merge that could not keep what it needs (std::bad_alloc, from
// a test hook) wakes a worker waiting in Lease, as any requeue does: it gets that job
// now. Before, nothing moved the change counter, and the tick wakes waiters only for
// leases expired, workers lost or a round announced, none of which comes here: the
// waiter returned empty at the end of its wait.
TEST(HostileMerges, AJobGivenBackWakesAWaitingLease) {
    // A merge that cannot keep what it needs, and a worker's failure that cannot be
    // counted: both give their job back.
    for (const bool by_fail : {false, true}) {
        CoordinatorOptions options;
        options.worker_lost_after = std::chrono::hours(1);  // no worker lost meanwhile
        Coordinator c(options);
        const std::string id =
            c.submit(square_test_spec("uniform", 64, 2048));  // two rounds
        const std::string a = c.register_worker("a", 8).session;
        const std::string b = c.register_worker("b", 8).session;
        // a takes every job there is: the round out's and, once it is open (then no round
        // is announced again), the round ahead's up to its bound.
        std::vector<LeaseGrant> out;
        bool ahead_open = false;
        for (int tries = 0; tries < 100; ++tries) {
            std::optional<LeaseGrant> g = c.lease(a, milliseconds(200));
            if (!g && ahead_open) break;
            if (!g) continue;
            ahead_open = ahead_open || g->job.first_sample[0] != 0;
            out.push_back(std::move(*g));
        }
        ASSERT_TRUE(ahead_open);
        const LeaseGrant& given = out.front();  // the round out's
        bool fail = true;
        c.with_session_for_test(id, [&](RenderSession& s) {
            (by_fail ? s.while_counting_failure : s.while_keeping) = [&](size_t) {
                if (std::exchange(fail, false)) throw std::bad_alloc();
            };
        });
        auto waiting = std::async(std::launch::async,
                                  [&] { return c.lease(b, milliseconds(3000)); });
        // So that b waits when the job comes back (too short only weakens this test).
        std::this_thread::sleep_for(milliseconds(200));
        if (by_fail)
            EXPECT_THROW(c.fail(a, given.lease_id, "crashed"), std::bad_alloc);
        else
            EXPECT_THROW(c.complete(a, given.lease_id, made_up_result(given)),
                         std::bad_alloc);
        // Not a time limit on anything: only so the regression fails rather than hangs.
        ASSERT_EQ(waiting.wait_for(std::chrono::seconds(60)), std::future_status::ready);
        const std::optional<LeaseGrant> got = waiting.get();
        ASSERT_TRUE(got) << "the waiting lease did not hear of the job given back"
                         << by_fail;
        EXPECT_TRUE(got->job.rect == given.job.rect);
        EXPECT_EQ(got->job.first_sample, given.job.first_sample);
    }
}

// A job of the round ahead, cut while a result of the round out is being added, counts
// that result's samples as to come: its cut waits for the add (issue). Cut before it, it
// would start its pixels' samples where the round out's job starts them, and trace
// them again.
TEST(HostileMerges, AJobOfTheRoundAheadCutDuringAnAddStartsAfterItsSamples) {
    Coordinator c(CoordinatorOptions{});
    const RenderSpec spec =
        square_test_spec("uniform", 64, 2048);  // two rounds of 1024 spp
    const std::string id = c.submit(spec);
    const std::string a = c.register_worker("a", 8).session;
    const std::string b = c.register_worker("b", 8).session;
    const std::optional<LeaseGrant> ga = c.lease(a, milliseconds(0));
    ASSERT_TRUE(ga);
    HeldAdd held;
    auto merge = merge_held(c, id, a, *ga, held);
    // b takes the round out's other jobs, then one of the round ahead over a's pixels.
    const PixelRect& ra = ga->job.rect;
    const auto overlaps = [&](const PixelRect& r) {
        return r.x < ra.x + ra.width && ra.x < r.x + r.width && r.y < ra.y + ra.height &&
               ra.y < r.y + r.height;
    };
    auto ahead = std::async(std::launch::async, [&]() -> std::optional<LeaseGrant> {
        for (int tries = 0; tries < 1000; ++tries) {
            std::optional<LeaseGrant> g = c.lease(b, milliseconds(20));
            if (!g) continue;
            if (overlaps(g->job.rect)) return g;
            c.complete(b, g->lease_id, made_up_result(*g));
        }
        return std::nullopt;
    });
    // Without the wait for the add it is cut meanwhile (a wait too short only makes this
    // test weaker, never wrong).
    ahead.wait_for(milliseconds(300));
    held.release.set_value();
    EXPECT_EQ(merge.get(), CompleteStatus::Merged);
    const std::optional<LeaseGrant> gb = ahead.get();
    ASSERT_TRUE(gb);
    c.complete(b, gb->lease_id, made_up_result(*gb));
    while (!is_terminal(c.info(id)->state))
        if (auto g = c.lease(b, milliseconds(20)))
            c.complete(b, g->lease_id, made_up_result(*g));
    ASSERT_EQ(c.info(id)->state, RenderState::Done);
    expect_same_image(*c.image(id, true), rendered_alone(spec), "uniform");
}

// An add that ends in anything but a refusal (here a test's hook throws what is no
// std::exception; in the farm, no memory left for a refusal's reason) still ends: the
// result is rejected and its job traced again. An add left open would hold up every
// wait for adds for good: the render's cancel, its images, and the tick behind them.
TEST(HostileMerges, AnAddEndingInAnyExceptionEndsAndItsJobIsTracedAgain) {
    Coordinator c(CoordinatorOptions{});
    const std::string id = c.submit(square_test_spec("uniform", 64, 4));
    const std::string a = c.register_worker("a", 8).session;
    const std::optional<LeaseGrant> ga = c.lease(a, milliseconds(0));
    ASSERT_TRUE(ga);
    std::atomic<bool> first{true};
    c.set_while_adding_for_test(id, [&](size_t) {
        if (first.exchange(false)) throw 33;
    });
    auto merge = std::async(std::launch::async, [&] {
        return c.complete(a, ga->lease_id, made_up_result(*ga)).status;
    });
    // Not a time limit on anything: only so the regression fails rather than hangs.
    ASSERT_EQ(merge.wait_for(std::chrono::seconds(20)), std::future_status::ready);
    EXPECT_NO_THROW(EXPECT_EQ(merge.get(), CompleteStatus::Rejected));
    auto cancel = std::async(std::launch::async, [&] { return c.cancel(id); });
    ASSERT_EQ(cancel.wait_for(std::chrono::seconds(20)), std::future_status::ready)
        << "the cancel waits for an add that never ends";
    EXPECT_EQ(cancel.get()->state, RenderState::Cancelled);
}

// Six workers on one render, rounds planned ahead and results held for them, while a
// tick expires leases: some results come unlike their jobs (refused after their lease
// ended, off the lock), some come after their lease expired and was issued again, some
// leases are given back, and two workers read the image as they go. Each job is added
// once, in round order: the render's bytes are those of one worker alone.
TEST(HostileMerges, RefusedExpiredAndAbandonedResultsEndAsOneWorkerAlone) {
    for (const auto& [method, spp] : std::vector<std::pair<const char*, uint32_t>>{
             {"uniform", 8192}, {"optimal", 16}, {"adaptive", 8192}, {"dammertz", 256}}) {
        const RenderSpec spec = square_test_spec(method, 64, spp);
        CoordinatorOptions options;
        options.lease_time = milliseconds(50);
        options.failure_policy.blocklist_after = 1000;  // refusals here are the test's
        options.failure_policy.max_job_failures = 1000;
        Coordinator c(options);
        const std::string id = c.submit(spec);
        std::mutex seen_mutex;
        std::set<std::pair<uint64_t, uint64_t>> seen;  // a job's corner, first sample
        std::atomic<bool> done{false};
        std::thread ticker([&] {
            while (!done) {
                c.tick();
                std::this_thread::sleep_for(milliseconds(2));
            }
        });
        std::vector<std::thread> threads;
        for (int w = 0; w < 6; ++w)
            threads.emplace_back([&, w] {
                std::mt19937 rng(w);
                std::string name = "w";  // appended: GCC 12 warns falsely on "w" + ...
                name += std::to_string(w);
                const std::string session = c.register_worker(name, 2).session;
                while (!is_terminal(c.info(id)->state)) {
                    const std::optional<LeaseGrant> grant =
                        c.lease(session, milliseconds(5));
                    if (!grant) continue;
                    SampleJobResult result = made_up_result(*grant);
                    const std::pair<uint64_t, uint64_t> job{
                        uint64_t(grant->job.rect.x) << 32 | grant->job.rect.y,
                        grant->job.first_sample.empty() ? 0 : grant->job.first_sample[0]};
                    bool first;
                    {
                        std::lock_guard lock(seen_mutex);
                        first = seen.insert(job).second;
                    }
                    const uint32_t roll = rng() % 20;
                    if (first && roll < 6) {
                        result.pixels[0].samples += 1;  // unlike its job: refused
                    } else if (roll == 6) {
                        std::this_thread::sleep_for(milliseconds(60));  // expires
                    } else if (roll == 7) {
                        c.abandon(session, grant->lease_id);
                        continue;
                    }
                    if (w % 2)
                        c.complete(session, grant->lease_id, std::move(result));
                    else
                        c.complete(session, grant->lease_id,
                                   static_cast<const SampleJobResult&>(result));
                    if (w == 0) (void)c.image(id, true);
                    if (w == 1)
                        c.read_sums(id, [](const Accumulator& a) { (void)a.at(0); });
                }
            });
        for (std::thread& t : threads) t.join();
        done = true;
        ticker.join();
        ASSERT_EQ(c.info(id)->state, RenderState::Done)
            << method << ": " << c.info(id)->error;
        expect_same_image(*c.image(id, true), rendered_alone(spec), method);
    }
}

}  // namespace
}  // namespace aliquot
