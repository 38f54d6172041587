#include "render_session.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <future>
#include <thread>

#include "checkpoint.h"
#include "denoised_strategy.h"
#include "scene_loader.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

uint64_t samples_of(const SampleJob& job) {
    uint64_t n = 0;
    for (uint32_t c : job.counts) n += c;
    return n;
}

// A result that satisfies its job without tracing: the session checks shape, not values.
SampleJobResult fake_result(const SampleJob& job) {
    SampleJobResult r;
    r.rect = job.rect;
    r.pixels.resize(job.rect.size());
    for (size_t i = 0; i < r.pixels.size(); ++i) {
        r.pixels[i].samples = job.counts[i];
        r.pixels[i].even[0] = 0.5 * double(job.counts[i]);
    }
    return r;
}

class RenderSessionTest : public ::testing::Test {
protected:
    RenderSessionTest() {
        spec.scene_name = "cornell-box";
        spec.scene_json = self_contained_scene_json("cornell-box");
        spec.width = 40;
        spec.height = 40;
        spec.strategy.method = "uniform";
        spec.strategy.spp = 8;
    }
    // `method` (optimal or optimal-time) at 64 spp, planning ahead rounds of at most
    // `plan_ahead` of the budget.
    void plan(const char* method, double plan_ahead) {
        spec.strategy.method = method;
        spec.strategy.spp = 64;
        spec.strategy.plan_ahead = plan_ahead;
    }

    // The buffers of spec's strategy driven round by round on `image`: what a session
    // must give however it runs the rounds (ahead, two out, resumed).
    Accumulator round_by_round(const SyntheticImage& image) const {
        Accumulator out(spec.width, spec.height);
        EXPECT_TRUE(run_synthetic(*make_strategy(spec.strategy, spec.width, spec.height),
                                  image, out)
                        .finished);
        return out;
    }

    // Bit for bit.
    static void expect_same_buffers(const Accumulator& got, const Accumulator& want) {
        ASSERT_EQ(got.pixel_count(), want.pixel_count());
        for (size_t i = 0; i < want.pixel_count(); ++i)
            ASSERT_EQ(got.at(i), want.at(i)) << i;
    }

    RenderSpec spec;
    RenderSession::Clock::time_point far =
        RenderSession::Clock::now() + std::chrono::hours(1);
};

TEST_F(RenderSessionTest, RunsRoundsUntilTheStrategyIsDone) {
    RenderSession s("r", spec, 0);
    std::vector<RoundSummary> rounds;
    s.on_round = [&](RenderSession&, const RoundSummary& r) { rounds.push_back(r); };
    s.start();
    uint64_t lease = 1;
    while (auto job = s.issue(lease, "w", far)) {
        EXPECT_EQ(s.complete(lease, "w", fake_result(*job)).status,
                  CompleteStatus::Merged);
        ++lease;
    }
    EXPECT_EQ(s.state(), RenderState::Done);
    EXPECT_EQ(s.merged().total_samples(), 8u * 40 * 40);
    ASSERT_FALSE(rounds.empty());
    EXPECT_EQ(rounds.back().samples_total, 8u * 40 * 40);
    for (size_t i = 0; i < rounds.size(); ++i) EXPECT_EQ(rounds[i].index, i);
}

TEST_F(RenderSessionTest, AStrategyThatReadsFirstHitsHasItsRenderTraceThem) {
    // denoised gives OIDN the first-hit albedo and normal: its render keeps them and its
    // jobs ask for them, though the submitter did not.
    spec.strategy.method = "denoised";
    spec.aux = false;
    const auto identity = [](const Image& in, const Image*, const Image*) { return in; };
    RenderSession s("r", spec, 0,
                    std::make_unique<DenoisedStrategy>(spec.strategy, spec.width,
                                                       spec.height, identity));
    EXPECT_TRUE(s.spec().aux);
    EXPECT_TRUE(s.aux().kept());
    s.start();
    const auto job = s.issue(1, "w", far);
    ASSERT_TRUE(job);
    EXPECT_TRUE(job->aux);
}

// A farm of 32 worker cores: the round is cut into at least 64 jobs, where the cut for a
// few workers (tiles of 64 on 256x256, 28 jobs) would leave half of them idle.
TEST_F(RenderSessionTest, ARoundIsCutIntoTwoJobsALiveWorkerCore) {
    spec.width = spec.height = 256;  // uniform, 8 spp: one round
    const auto jobs_of_first_round = [&](size_t cores) {
        RenderSession s("r", spec, 0);
        if (cores) s.set_worker_cores(cores);
        s.start();
        size_t jobs = 0;
        uint64_t samples = 0;
        while (auto job = s.issue(jobs + 1, "w", far))
            ++jobs, samples += samples_of(*job);
        EXPECT_EQ(samples, 8u * 256 * 256);
        return jobs;
    };
    EXPECT_EQ(jobs_of_first_round(0), 28u);
    EXPECT_GE(jobs_of_first_round(32), 64u);
}

TEST_F(RenderSessionTest, ReissuesAnExpiredLeaseAndIgnoresItsLateResult) {
    RenderSession s("r", spec, 0);
    s.start();
    const auto now = RenderSession::Clock::now();
    auto job = s.issue(1, "slow", now + std::chrono::milliseconds(1));
    ASSERT_TRUE(job);
    EXPECT_EQ(s.expire(now + std::chrono::seconds(1)).size(), 1u);
    auto again = s.issue(2, "fast", far);
    ASSERT_TRUE(again);
    EXPECT_EQ(again->rect, job->rect);
    EXPECT_EQ(s.complete(1, "slow", fake_result(*job)).status, CompleteStatus::Ignored);
    EXPECT_EQ(s.complete(2, "fast", fake_result(*again)).status, CompleteStatus::Merged);
    EXPECT_EQ(s.merged().total_samples(), samples_of(*job));  // merged once, not twice
}

// Found by fuzz/job_result_fuzz: a result whose merged sums would not stay finite threw
// out of complete() after its lease was forgotten, so the job was never traced again.
TEST_F(RenderSessionTest, AResultThatWouldOverflowTheSumsIsRejectedAndTheJobReissued) {
    RenderSession s("r", spec, 0);
    s.start();
    auto job = s.issue(1, "w", far);
    ASSERT_TRUE(job);
    SampleJobResult huge = fake_result(*job);
    huge.pixels[0].even[0] = 1.7e308;
    const CompleteOutcome out = s.complete(1, "w", huge);
    EXPECT_EQ(out.status, CompleteStatus::Rejected);
    EXPECT_NE(out.message.find("non-finite or larger than 1e30"), std::string::npos)
        << out.message;
    EXPECT_EQ(s.merged().total_samples(), 0u);
    auto again = s.issue(2, "w", far);
    ASSERT_TRUE(again);
    EXPECT_EQ(again->rect, job->rect);
    EXPECT_EQ(s.complete(2, "w", fake_result(*again)).status, CompleteStatus::Merged);
}

// Issue 30, item 8: the lease holder's sums of 9e99 stayed under the old cap of 1e100,
// merged, and the finished 32x32 image held +inf wherever a pixel had one sample, with
// an error estimate of 0. Such a result is refused whole and counted as a failed job,
// which is traced again; the render ends with every pixel finite.
TEST_F(RenderSessionTest,
       AResultWhoseMeanOverflowsAFloatIsRefusedAndTheImageStaysFinite) {
    spec.width = spec.height = 32;
    spec.strategy.spp = 1;
    RenderSession s("r", spec, 0);
    s.start();
    uint64_t lease = 0;
    bool poisoned = false;
    // Another worker after the refusal: the one refused may be kept off the job.
    while (auto job = s.issue(++lease, poisoned ? "v" : "w", far)) {
        SampleJobResult r = fake_result(*job);
        if (!poisoned) {
            SampleJobResult huge = r;
            for (PixelSums& p : huge.pixels) p.even[0] = p.odd[1] = 9e99;
            const CompleteOutcome out = s.complete(lease, "w", huge);
            EXPECT_EQ(out.status, CompleteStatus::Rejected);
            EXPECT_NE(out.message.find("larger than 1e30 a sample"), std::string::npos)
                << out.message;
            poisoned = true;
            continue;  // the job comes back with the next lease
        }
        ASSERT_EQ(s.complete(lease, "v", r).status, CompleteStatus::Merged);
    }
    ASSERT_EQ(s.state(), RenderState::Done);
    const Image image = s.image(true);
    for (float v : image.rgb) ASSERT_TRUE(std::isfinite(v));
    for (const Image::Channel& c : image.extra)
        for (float v : c.values) ASSERT_TRUE(std::isfinite(v)) << c.name;
    EXPECT_EQ(s.merged().total_samples(), 32u * 32u);
}

TEST_F(RenderSessionTest, APixelWithoutSamplesMustComeBackEmpty) {
    // A steered round gives some pixels of a job's tile no samples; a worker that returns
    // light, rays or variance there changes the image where nothing was traced.
    spec.strategy.method = "optimal";
    spec.strategy.spp = 0;
    spec.strategy.budget = 40 * 40 * 16;
    RenderSession s("r", spec, 0);
    s.start();
    const FailurePolicy patient{100, 100};  // the render outlives the rejections below
    uint64_t lease = 0;
    // The next job that has a pixel of no samples, completing the others as they come.
    const auto job_with_an_empty_pixel = [&]() -> std::pair<SampleJob, size_t> {
        while (true) {
            auto job = s.issue(++lease, "w", far, {}, patient);
            if (!job) return {};
            const auto it = std::find(job->counts.begin(), job->counts.end(), 0u);
            if (s.rounds_done() > 0 && it != job->counts.end())
                return {*job, size_t(it - job->counts.begin())};
            EXPECT_EQ(s.complete(lease, "w", fake_result(*job), {}, patient).status,
                      CompleteStatus::Merged);
        }
    };
    for (int field = 0; field < 3; ++field) {
        const auto [job, empty] = job_with_an_empty_pixel();
        ASSERT_FALSE(job.counts.empty()) << "no steered job left a pixel empty";
        const uint64_t before = s.merged().total_samples();
        SampleJobResult r = fake_result(job);
        if (field == 0) r.pixels[empty].even[1] = 0.25;
        if (field == 1) r.pixels[empty].rays = 7;
        if (field == 2) r.pixels[empty].sum_sq_luminance = 1;
        const CompleteOutcome out = s.complete(lease, "w", r, {}, patient);
        EXPECT_EQ(out.status, CompleteStatus::Rejected) << field;
        EXPECT_NE(out.message.find("no samples but non-zero sums"), std::string::npos)
            << out.message;
        EXPECT_EQ(s.merged().total_samples(), before);
    }
    // The same jobs, returned empty where they should be, finish the render.
    while (auto job = s.issue(++lease, "w", far, {}, patient))
        ASSERT_EQ(s.complete(lease, "w", fake_result(*job), {}, patient).status,
                  CompleteStatus::Merged);
    EXPECT_EQ(s.state(), RenderState::Done);
    EXPECT_EQ(s.merged().total_samples(), 40u * 40 * 16);
}

TEST_F(RenderSessionTest, RenewKeepsALeaseAliveOnlyForItsOwner) {
    RenderSession s("r", spec, 0);
    s.start();
    const auto now = RenderSession::Clock::now();
    ASSERT_TRUE(s.issue(1, "w", now + std::chrono::milliseconds(1)));
    EXPECT_FALSE(s.renew(1, "intruder", far));
    EXPECT_TRUE(s.renew(1, "w", far));
    EXPECT_TRUE(s.expire(now + std::chrono::seconds(1)).empty());
}

// Issue 13: a worker could complete another's lease (its sums merged, the holder's result
// then ignored) or, with a wrong rectangle, get the holder's work rejected.
TEST_F(RenderSessionTest, OnlyTheHolderCompletesRenewsAbandonsOrFailsALease) {
    RenderSession s("r", spec, 0);
    s.start();
    const auto job = s.issue(1, "holder", far);
    ASSERT_TRUE(job);
    SampleJobResult bogus = fake_result(*job);
    for (PixelSums& p : bogus.pixels)
        for (int c = 0; c < 3; ++c) p.even[c] = p.odd[c] = 100 * double(p.samples);
    const CompleteOutcome out = s.complete(1, "intruder", bogus);
    EXPECT_EQ(out.status, CompleteStatus::Ignored);
    EXPECT_EQ(out.message, "not your lease");
    SampleJobResult wrong = fake_result(*job);
    wrong.rect.x += 1;  // would be rejected, and the job re-issued, if it were heard
    EXPECT_EQ(s.complete(1, "intruder", wrong).status, CompleteStatus::Ignored);
    EXPECT_FALSE(s.renew(1, "intruder", far));
    EXPECT_FALSE(s.abandon(1, "intruder"));
    EXPECT_FALSE(s.fail_job(1, "intruder", "no", {"holder", "intruder"}, {}));
    EXPECT_EQ(s.failures_of("intruder"), 0u);
    EXPECT_TRUE(s.holds(1));
    EXPECT_EQ(s.merged().total_samples(), 0u);
    EXPECT_EQ(s.complete(1, "holder", fake_result(*job)).status, CompleteStatus::Merged);
    EXPECT_EQ(s.merged().total_samples(), samples_of(*job));
    const PixelSums& first =
        s.merged().at(size_t(job->rect.y) * spec.width + job->rect.x);
    EXPECT_EQ(first.even[0], 0.5 * double(job->counts[0]));  // the holder's, not 100s
}

TEST_F(RenderSessionTest, CancelKeepsWhatWasMergedAndIgnoresTheRest) {
    spec.width = 300;  // wide enough for the first round to have several jobs
    RenderSession s("r", spec, 0);
    s.start();
    auto a = s.issue(1, "w", far);
    auto b = s.issue(2, "w", far);
    ASSERT_TRUE(a && b);
    ASSERT_EQ(s.complete(1, "w", fake_result(*a)).status, CompleteStatus::Merged);
    s.cancel();
    EXPECT_EQ(s.state(), RenderState::Cancelled);
    EXPECT_EQ(s.complete(2, "w", fake_result(*b)).status, CompleteStatus::Ignored);
    EXPECT_EQ(s.merged().total_samples(), samples_of(*a));
    EXPECT_FALSE(s.issue(3, "w", far));
}

// Found in review: a checkpoint of another size was restored as it was, and every round
// after it indexed the buffers out of bounds.
TEST_F(RenderSessionTest, ACheckpointOfAnotherSizeIsRefused) {
    RenderSession s("r", spec, 0);
    EXPECT_THROW(s.restore(Accumulator(spec.width + 1, spec.height),
                           nlohmann::json::object(), 1, 0),
                 std::runtime_error);
}

TEST_F(RenderSessionTest, RestoredSessionPlansTheSameRoundsAsAnUninterruptedOne) {
    // Enough samples for three rounds: uniform's first holds about kFirstRoundSamples.
    spec.strategy.spp = uint32_t(2 * kFirstRoundSamples / (40 * 40) + 100);
    auto run = [&](int interrupt_after_round) {
        RenderSession s("r", spec, 0);
        std::optional<std::pair<Accumulator, nlohmann::json>> saved;
        uint32_t saved_rounds = 0;
        s.on_round = [&](RenderSession& r, const RoundSummary& round) {
            if (int(round.index) == interrupt_after_round) {
                saved.emplace(r.merged(), r.strategy().save_state());
                saved_rounds = r.rounds_done();
            }
        };
        s.start();
        uint64_t lease = 1;
        while (auto job = s.issue(lease, "w", far))
            s.complete(lease++, "w", fake_result(*job));
        if (interrupt_after_round < 0) return s.merged().image(true).rgb;
        RenderSession resumed("r", spec, 0);
        resumed.restore(saved->first, saved->second, saved_rounds, 0);
        resumed.start();
        while (auto job = resumed.issue(lease, "w", far))
            resumed.complete(lease++, "w", fake_result(*job));
        EXPECT_EQ(resumed.state(), RenderState::Done);
        return resumed.merged().image(true).rgb;
    };
    EXPECT_EQ(run(-1), run(1));
}

TEST_F(RenderSessionTest, RoundsPlannedAheadGiveTheBuffersOfAStrategyThatPlansInPlace) {
    // The session runs optimal's work ahead on its own thread while the round out
    // merges; the buffers must be those of the strategy driven round by round. A
    // checkpoint taken at any round end, one where a round is planned ahead too (with
    // that round's counts), resumes to the same buffers again. plan_ahead 1 splits the
    // pilot: a checkpoint after its first half holds the second as the round planned.
    const SyntheticImage image(40, 40, 7, {0.5, 0.3, 1, 0.01, 20});
    for (const char* method : {"optimal", "optimal-time"})
        for (const double plan_ahead : {1.0 / 8, 1.0}) {
            SCOPED_TRACE(std::string(method) + " " + std::to_string(plan_ahead));
            plan(method, plan_ahead);
            const Accumulator in_place = round_by_round(image);
            const auto render = [&](const Checkpoint* from,
                                    std::vector<Checkpoint>* taken) {
                RenderSession s("r", spec, 0);
                uint32_t held = 0;
                s.on_round = [&](RenderSession& r, const RoundSummary&) {
                    const std::vector<uint32_t>* planned =
                        r.strategy().round_planned_ahead();
                    // Held and none: the plan ahead found the budget spent, and this
                    // round end is the render's (the coordinator takes no checkpoint).
                    if (r.strategy().holds_planned_round() && ++held && !planned) return;
                    if (!taken) return;
                    Checkpoint& cp = taken->emplace_back();
                    cp.merged.copy_from(r.merged());
                    cp.strategy_state = r.strategy().save_state();
                    cp.rounds_done = r.rounds_done();
                    if (planned) cp.planned_round = *planned;
                };
                if (from) {
                    Accumulator copy;
                    copy.copy_from(from->merged);
                    s.restore(std::move(copy), from->strategy_state, from->rounds_done, 0,
                              from->planned_round);
                }
                s.start();
                uint64_t lease = 1;
                while (auto job = s.issue(lease, "w", far))
                    EXPECT_EQ(s.complete(lease++, "w", image.trace(*job)).status,
                              CompleteStatus::Merged);
                EXPECT_EQ(s.state(), RenderState::Done);
                if (!from) {
                    EXPECT_GT(held, 2u);
                }
                Accumulator out;
                out.copy_from(s.merged());
                return out;
            };
            std::vector<Checkpoint> taken;
            const Accumulator whole = render(nullptr, &taken);
            ASSERT_GT(taken.size(), 3u);
            for (size_t i = 0; i < in_place.pixel_count(); ++i)
                ASSERT_EQ(whole.at(i), in_place.at(i)) << i;
            // Resumed with a round planned ahead: at several round ends, and at 1 after
            // the pilot's first half, whose second half is the round held.
            EXPECT_GT(std::count_if(
                          taken.begin(), taken.end(),
                          [](const Checkpoint& cp) { return !cp.planned_round.empty(); }),
                      2);
            if (plan_ahead == 1) {
                EXPECT_FALSE(taken[0].planned_round.empty());
            }
            for (size_t c = 0; c < taken.size(); ++c) {
                SCOPED_TRACE("resumed after round " + std::to_string(c));
                const Accumulator resumed = render(&taken[c], nullptr);
                for (size_t i = 0; i < in_place.pixel_count(); ++i)
                    ASSERT_EQ(resumed.at(i), in_place.at(i)) << i;
            }
        }
}

// Two rounds out: once every job of a round is leased, the round planned ahead opens and
// its jobs are leased while the round out's last job is traced; their results are held
// until that one merges. Driven with a straggler in every round (once expiring and
// traced again), results coming back newest first, the buffers are those of the
// strategy driven round by round.
TEST_F(RenderSessionTest, TheRoundAfterIsTracedWhileTheRoundOutsLastJobIs) {
    const SyntheticImage image(40, 40, 7, {0.5, 0.3, 1, 0.01, 20});
    for (const char* method : {"optimal", "optimal-time"}) {
        SCOPED_TRACE(method);
        plan(method, 1);  // every steered round planned ahead
        const Accumulator in_place = round_by_round(image);
        RenderSession s("r", spec, 0);
        s.start();
        struct Out {
            uint64_t lease;
            SampleJob job;
        };
        std::deque<Out> out;  // oldest first
        uint64_t next_lease = 1;
        const auto lease_all = [&] {
            size_t n = 0;
            while (auto job = s.issue(next_lease, "w", far)) {
                out.push_back({next_lease++, std::move(*job)});
                ++n;
            }
            return n;
        };
        size_t held = 0, expired = 0;
        for (int step = 0; s.state() == RenderState::Running; ++step) {
            ASSERT_LT(step, 10000);
            lease_all();
            const auto give = [&](const Out& o) {  // merged, or held
                const uint64_t before = s.merged().total_samples();
                ASSERT_EQ(s.complete(o.lease, "w", image.trace(o.job)).status,
                          CompleteStatus::Merged);
                if (s.merged().total_samples() == before) ++held;
            };
            // All but the oldest come back, newest first.
            const auto all_but_the_oldest = [&] {
                for (; out.size() > 1; out.pop_back()) give(out.back());
            };
            all_but_the_oldest();
            // The oldest is the straggler: the round after opens once its plan is made.
            for (int spin = 0; spin < 2000 && lease_all() == 0 && s.has_pending(); ++spin)
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            if (step % 2) all_but_the_oldest();  // the round after's come back first
            if (out.size() > 1 && expired == 0) {
                // Its lease runs out: it goes back ahead of the round after's jobs.
                const Out late = out.front();
                out.pop_front();
                ASSERT_EQ(s.expire(far + std::chrono::hours(1)).size(), out.size() + 1);
                ++expired;
                out.clear();  // every lease expired: all are traced again
                ASSERT_TRUE(lease_all() > 0);
                EXPECT_TRUE(out.front().job.rect == late.job.rect);
                EXPECT_EQ(s.complete(late.lease, "w", image.trace(late.job)).status,
                          CompleteStatus::Ignored);
            }
            // The straggler first, then what opened after it.
            for (; !out.empty(); out.pop_front()) give(out.front());
        }
        EXPECT_EQ(s.state(), RenderState::Done);
        EXPECT_GT(held, 0u);
        EXPECT_EQ(expired, 1u);
        expect_same_buffers(s.merged(), in_place);
    }
}

// uniform's rounds follow from its state alone: each is handed to the farm while the one
// before it is out, so a round end is never waited through, and the buffers are those of
// the strategy driven round by round.
TEST_F(RenderSessionTest, UniformOpensEachRoundWhileTheRoundBeforeIsOut) {
    spec.width = 512;  // two rounds of 32 spp: uniform's rounds start at 2^22 samples
    spec.height = 256;
    spec.strategy.spp = 64;
    const SyntheticImage image(512, 256, 3, {0.5, 0.2});
    const Accumulator in_place = round_by_round(image);
    RenderSession s("r", spec, 0);
    s.start();
    std::vector<std::pair<uint64_t, SampleJob>> out;
    uint64_t lease = 1;
    while (auto job = s.issue(lease, "w", far))
        out.emplace_back(lease++, std::move(*job));
    ASSERT_GT(out.size(), 1u);
    // All of round 0 but its last job merge; the round after opens once its counts are
    // made (off the caller's thread).
    for (size_t j = 0; j + 1 < out.size(); ++j)
        ASSERT_EQ(s.complete(out[j].first, "w", image.trace(out[j].second)).status,
                  CompleteStatus::Merged);
    std::optional<SampleJob> next;
    for (int spin = 0; spin < 2000 && !(next = s.issue(lease, "w", far)); ++spin)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ASSERT_TRUE(next.has_value());
    const uint64_t next_lease = lease++;
    ASSERT_EQ(s.complete(out.back().first, "w", image.trace(out.back().second)).status,
              CompleteStatus::Merged);
    EXPECT_TRUE(s.round_opened_ahead());
    ASSERT_EQ(s.complete(next_lease, "w", image.trace(*next)).status,
              CompleteStatus::Merged);
    while (auto job = s.issue(lease, "w", far))
        ASSERT_EQ(s.complete(lease++, "w", image.trace(*job)).status,
                  CompleteStatus::Merged);
    EXPECT_EQ(s.state(), RenderState::Done);
    expect_same_buffers(s.merged(), in_place);
}

// adaptive's deliveries after its decision follow from its state alone: each is handed
// to the farm while the one before it is out (the pilot's end, which decides, is still
// waited through), and the buffers are those of the strategy driven round by round.
TEST_F(RenderSessionTest, AdaptiveOpensEachDeliveryWhileTheOneBeforeIsOut) {
    spec.width = 256;
    spec.height = 256;
    spec.strategy.method = "adaptive";
    spec.strategy.spp = 1100;  // 72 M samples: three deliveries of at most 2^25
    const SyntheticImage image(256, 256, 3, {0.5, 0.2});
    const Accumulator in_place = round_by_round(image);
    RenderSession s("r", spec, 0);
    s.start();
    uint64_t lease = 1;
    size_t opened_ahead = 0;
    for (int round = 0; s.state() == RenderState::Running; ++round) {
        ASSERT_LT(round, 100);
        std::vector<std::pair<uint64_t, SampleJob>> out;
        while (auto job = s.issue(lease, "w", far))
            out.emplace_back(lease++, std::move(*job));
        ASSERT_FALSE(out.empty());
        for (size_t j = 0; j + 1 < out.size(); ++j)
            ASSERT_EQ(s.complete(out[j].first, "w", image.trace(out[j].second)).status,
                      CompleteStatus::Merged);
        // With the round's last job out, a delivery made ahead opens (off this thread).
        std::optional<SampleJob> next;
        for (int spin = 0; spin < 500 && !(next = s.issue(lease, "w", far)); ++spin)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        const uint64_t next_lease = lease++;
        ASSERT_EQ(
            s.complete(out.back().first, "w", image.trace(out.back().second)).status,
            CompleteStatus::Merged);
        if (!next) continue;
        ++opened_ahead;
        EXPECT_TRUE(s.round_opened_ahead());
        ASSERT_EQ(s.complete(next_lease, "w", image.trace(*next)).status,
                  CompleteStatus::Merged);
    }
    EXPECT_GE(opened_ahead, 2u);
    EXPECT_EQ(s.state(), RenderState::Done);
    expect_same_buffers(s.merged(), in_place);
}

// optimal planning every steered round ahead on a banded image, and the buffers it must
// give.
class TwoRoundsOutTest : public RenderSessionTest {
protected:
    TwoRoundsOutTest() {
        plan("optimal", 1);
        in_place = round_by_round(image);
    }
    const SyntheticImage image{40, 40, 7, {0.5, 0.3, 1, 0.01, 20}};
    Accumulator in_place;
};

// The round after's jobs leased or held cover at most half the image: a round-k job that
// does not come back cannot make the coordinator hold a whole round.
TEST_F(TwoRoundsOutTest, WhatTheRoundAfterHoldsIsHalfTheImageAtMost) {
    RenderSession s("r", spec, 0);
    s.start();
    uint64_t lease = 1;
    size_t capped = 0;
    const auto lease_all = [&](std::vector<std::pair<uint64_t, SampleJob>>& out) {
        size_t n = 0;
        for (; auto job = s.issue(lease, "w", far); ++n) out.emplace_back(lease++, *job);
        return n;
    };
    const auto give = [&](const std::pair<uint64_t, SampleJob>& o) {
        ASSERT_EQ(s.complete(o.first, "w", image.trace(o.second)).status,
                  CompleteStatus::Merged);
    };
    for (int step = 0; s.state() == RenderState::Running; ++step) {
        ASSERT_LT(step, 10000);
        std::vector<std::pair<uint64_t, SampleJob>> out, after;
        lease_all(out);
        ASSERT_FALSE(out.empty());
        for (size_t k = 1; k < out.size(); ++k) give(out[k]);
        // The first is out: lease what the round after allows, all of it held back.
        for (int spin = 0; spin < 2000 && lease_all(after) == 0 && s.has_pending();
             ++spin)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        size_t pixels = 0;
        for (const auto& o : after) pixels += o.second.rect.size();
        if (after.size() > 1) {
            EXPECT_LE(pixels, 40u * 40 / 2);
        }
        for (const auto& o : after) give(o);  // held: they still count
        std::vector<std::pair<uint64_t, SampleJob>> more;
        if (!after.empty()) {
            EXPECT_EQ(lease_all(more), 0u);
            capped += s.has_pending();  // jobs were left: the cap held them back
        }
        give(out[0]);
        for (const auto& o : more) give(o);
    }
    EXPECT_GT(capped, 0u);
    EXPECT_EQ(s.state(), RenderState::Done);
    expect_same_buffers(s.merged(), in_place);
}

// A held result is checked when it comes, but only its merge, after the round before's,
// can refuse sums that would stop being finite: it is then a rejected result, counted
// against its worker, and its job is traced again.
TEST_F(TwoRoundsOutTest, AHeldResultTheMergeRefusesIsTracedAgain) {
    RenderSession s("r", spec, 0);
    s.start();
    uint64_t lease = 1;
    bool poisoned = false;
    for (int step = 0; s.state() == RenderState::Running; ++step) {
        ASSERT_LT(step, 10000);
        std::vector<std::pair<uint64_t, SampleJob>> out;
        while (auto job = s.issue(lease, "w", far)) out.emplace_back(lease++, *job);
        ASSERT_FALSE(out.empty());
        // All but the first back; then, once, a job of the round after while the first
        // is still out.
        for (size_t k = out.size(); k-- > 1;)
            ASSERT_EQ(s.complete(out[k].first, "w", image.trace(out[k].second)).status,
                      CompleteStatus::Merged);
        if (!poisoned) {
            std::optional<SampleJob> ahead;
            for (int spin = 0;
                 spin < 2000 && !(ahead = s.issue(lease, "w", far)) && s.has_pending();
                 ++spin)
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            if (ahead) {
                SampleJobResult huge = image.trace(*ahead);
                const auto traced =
                    std::find_if(huge.pixels.begin(), huge.pixels.end(),
                                 [](const PixelSums& p) { return p.samples; });
                ASSERT_NE(traced, huge.pixels.end());
                traced->even[0] = 1.7e308;
                const CompleteOutcome o = s.complete(lease++, "w", huge);
                ASSERT_EQ(o.status, CompleteStatus::Merged) << o.message;
                poisoned = true;
                EXPECT_EQ(s.failures_of("w"), 0u);
            }
        }
        ASSERT_EQ(s.complete(out[0].first, "w", image.trace(out[0].second)).status,
                  CompleteStatus::Merged);
        if (poisoned) {
            EXPECT_LE(s.failures_of("w"), 1u);
        }
    }
    EXPECT_TRUE(poisoned);
    EXPECT_EQ(s.failures_of("w"), 1u);
    EXPECT_EQ(s.state(), RenderState::Done);
    expect_same_buffers(s.merged(), in_place);
}

// A strategy whose plan, made ahead on the session's thread, throws (as a plan that
// runs out of memory would): after a first round of one sample a pixel.
class ThrowingAhead : public Strategy {
public:
    std::string name() const override { return "throwing"; }
    std::optional<Round> next_round(const Accumulator& merged) override {
        if (work_taken_) return std::nullopt;  // never reached: the render has failed
        return Round{0, std::vector<uint32_t>(merged.pixel_count(), 1)};
    }
    std::function<void()> take_work_ahead() override {
        if (work_taken_) return {};
        work_taken_ = true;
        return [] { throw std::runtime_error("out of memory, say"); };
    }
    uint64_t planned_samples() const override { return 0; }
    nlohmann::json save_state() const override { return nlohmann::json::object(); }
    void restore_state(const nlohmann::json&) override {}

private:
    bool work_taken_ = false;
};

TEST_F(RenderSessionTest, APlanThatThrowsAheadFailsTheRenderWithTheReason) {
    RenderSession s("r", spec, 0, std::make_unique<ThrowingAhead>());
    s.start();
    uint64_t lease = 1;
    while (auto job = s.issue(lease, "w", far))
        EXPECT_EQ(s.complete(lease++, "w", fake_result(*job)).status,
                  CompleteStatus::Merged);
    EXPECT_EQ(s.state(), RenderState::Failed);
    EXPECT_EQ(s.error(), "cannot plan round 1: out of memory, say");
    EXPECT_EQ(s.merged().total_samples(), 40u * 40);  // what merged is kept
}

// Two rounds of one sample a pixel, the second planned ahead by work that waits until the
// test lets it go: a plan that is late for the leases.
class LateAhead : public Strategy {
public:
    std::string name() const override { return "late"; }
    std::optional<Round> next_round(const Accumulator& merged) override {
        if (rounds_ == 2) return std::nullopt;
        if (rounds_++ == 0)
            return Round{0, std::vector<uint32_t>(merged.pixel_count(), 1)};
        return Round{1, std::move(ahead_)};
    }
    std::function<void()> take_work_ahead() override {
        if (rounds_ != 1 || taken_) return {};
        taken_ = true;
        return [this] {
            released_.get_future().wait();
            ahead_.assign(40 * 40, 1);
        };
    }
    const std::vector<uint32_t>* round_planned_ahead() const override {
        return ahead_.empty() ? nullptr : &ahead_;
    }
    uint64_t planned_samples() const override { return 2 * 40 * 40; }
    nlohmann::json save_state() const override { return nlohmann::json::object(); }
    void restore_state(const nlohmann::json&) override {}
    std::promise<void> released_;

private:
    int rounds_ = 0;
    bool taken_ = false;
    std::vector<uint32_t> ahead_;
};

TEST_F(RenderSessionTest, ALatePlanAheadIsTimedAsAWaitOnTheCoordinator) {
    auto strategy = std::make_unique<LateAhead>();
    LateAhead& late = *strategy;
    RenderSession s("r", spec, 0, std::move(strategy));
    s.start();
    std::vector<std::pair<uint64_t, SampleJob>> out;
    uint64_t lease = 1;
    while (auto job = s.issue(lease, "w", far))
        out.emplace_back(lease++, std::move(*job));
    EXPECT_EQ(s.plan_wait_seconds(), 0.0);  // asked, found nothing: the clock runs
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    late.released_.set_value();
    std::optional<SampleJob> next;
    for (int spin = 0; spin < 2000 && !(next = s.issue(lease, "w", far)); ++spin)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ASSERT_TRUE(next.has_value());
    EXPECT_GE(s.plan_wait_seconds(), 0.03);
    const double waited = s.plan_wait_seconds();
    for (const auto& [l, job] : out)
        ASSERT_EQ(s.complete(l, "w", fake_result(job)).status, CompleteStatus::Merged);
    ASSERT_EQ(s.complete(lease, "w", fake_result(*next)).status, CompleteStatus::Merged);
    while (auto job = s.issue(++lease, "w", far))
        ASSERT_EQ(s.complete(lease, "w", fake_result(*job)).status,
                  CompleteStatus::Merged);
    EXPECT_EQ(s.state(), RenderState::Done);
    EXPECT_EQ(s.plan_wait_seconds(), waited);  // the round ends were not counted here
}

// Issue 12, item 5: a job a worker cannot trace goes to another worker; failures count
// per job and per worker, and a job nobody can trace fails the render with the reason.
class FailingJobsTest : public RenderSessionTest {
protected:
    static std::string where(const SampleJob& job) {
        return "job " + std::to_string(job.rect.x) + "," + std::to_string(job.rect.y) +
               " " + std::to_string(job.rect.width) + "x" +
               std::to_string(job.rect.height);
    }
    FailurePolicy policy;  // 3 distinct workers fail a render; 2 failures blocklist
};

TEST_F(FailingJobsTest, AFailedJobGoesToAnotherWorkerNotBackToTheSame) {
    RenderSession s("r", spec, 0);
    s.start();
    const std::set<std::string> alive{"a", "b"};
    const auto job = s.issue(1, "a", far, alive, policy);
    ASSERT_TRUE(job);
    EXPECT_FALSE(s.fail_job(1, "b", "not b's lease", alive, policy));
    EXPECT_TRUE(s.fail_job(1, "a", "cannot open mesh.obj", alive, policy));
    EXPECT_FALSE(s.holds(1));
    EXPECT_EQ(s.state(), RenderState::Running);
    EXPECT_EQ(s.failures_of("a"), 1u);
    const auto other = s.issue(2, "a", far, alive, policy);
    ASSERT_TRUE(other);
    EXPECT_FALSE(other->rect == job->rect);  // a gets another job ...
    const auto again = s.issue(3, "b", far, alive, policy);
    ASSERT_TRUE(again);
    EXPECT_EQ(again->rect, job->rect);  // ... and b the one that failed on a
}

TEST_F(FailingJobsTest, AJobThatFailedOnKDistinctWorkersFailsTheRenderWithTheReason) {
    RenderSession s("r", spec, 0);
    int finished = 0;
    s.on_finished = [&](RenderSession&) { ++finished; };
    s.start();
    const std::set<std::string> alive{"a", "b", "c", "d"};
    std::optional<SampleJob> first;
    uint64_t lease = 1;
    for (const char* w : {"a", "b", "c"}) {
        const auto job = s.issue(lease, w, far, alive, policy);
        ASSERT_TRUE(job);
        if (!first) first = job;
        EXPECT_EQ(job->rect, first->rect) << w;  // the failed job first, to a new worker
        EXPECT_TRUE(s.fail_job(lease++, w, "cannot open\nmesh.obj", alive, policy));
    }
    EXPECT_EQ(s.state(), RenderState::Failed);
    EXPECT_EQ(s.error(), where(*first) + " failed on 3 workers: cannot open mesh.obj");
    EXPECT_EQ(finished, 1);
    EXPECT_FALSE(s.issue(lease, "d", far, alive, policy));
}

// Found in review: a reason cut at 500 bytes could split a UTF-8 character, and the
// render's error then broke every JSON and proto string that carried it.
TEST_F(FailingJobsTest, TheReasonKeptIsPrintableAsciiAndBounded) {
    RenderSession s("r", spec, 0);
    s.start();
    const std::set<std::string> alive{"a"};
    const std::string reason =
        std::string(499, 'x') + "\xc3\xa9\xff" + std::string(100, 'y');
    for (uint64_t lease = 1; s.state() == RenderState::Running; ++lease) {
        ASSERT_TRUE(s.issue(lease, "a", far, alive, policy));
        EXPECT_TRUE(s.fail_job(lease, "a", reason, alive, policy));
    }
    EXPECT_EQ(s.state(), RenderState::Failed);
    for (char c : s.error()) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << int(c);
    EXPECT_LT(s.error().size(), 600u);
}

// Found in review: a rejected result put its job back at the front with nothing counted,
// so a worker that always returned a bad result leased, was rejected and leased again for
// ever. Rejections now count as failures.
TEST_F(FailingJobsTest, AWorkerWhoseResultsAreAlwaysRejectedFailsTheRender) {
    RenderSession s("r", spec, 0);
    s.start();
    const std::set<std::string> alive{"a"};
    uint64_t lease = 1;
    for (; s.state() == RenderState::Running && lease < 10; ++lease) {
        const auto job = s.issue(lease, "a", far, alive, policy);
        ASSERT_TRUE(job);
        SampleJobResult bad = fake_result(*job);
        bad.pixels.pop_back();  // the wrong pixel count
        EXPECT_EQ(s.complete(lease, "a", bad, alive, policy).status,
                  CompleteStatus::Rejected);
    }
    EXPECT_EQ(s.state(), RenderState::Failed);
    EXPECT_EQ(lease - 1, policy.max_job_failures);
    EXPECT_NE(s.error().find("result rejected: "), std::string::npos) << s.error();
}

TEST_F(FailingJobsTest, AWorkerThatKeepsFailingIsKeptOffTheRender) {
    RenderSession s("r", spec, 0);
    s.start();
    const std::set<std::string> alive{"bad", "good"};
    for (uint64_t lease = 1; lease <= 2; ++lease) {
        ASSERT_TRUE(s.issue(lease, "bad", far, alive, policy));
        ASSERT_TRUE(s.fail_job(lease, "bad", "no Embree here", alive, policy));
    }
    EXPECT_EQ(s.failures_of("bad"), 2u);
    EXPECT_FALSE(s.issue(3, "bad", far, alive, policy));  // blocklisted while good lives
    EXPECT_TRUE(s.issue(4, "good", far, alive, policy));
    // With nobody else left, it is tried again rather than the render stalling.
    EXPECT_TRUE(s.issue(5, "bad", far, {"bad"}, policy));
    EXPECT_EQ(s.state(), RenderState::Running);
}

TEST_F(FailingJobsTest, ALoneWorkerFailsTheRenderAfterKFailuresInAll) {
    RenderSession s("r", spec, 0);
    s.start();
    const std::set<std::string> alive{"only"};
    std::optional<SampleJob> first;
    for (uint64_t lease = 1; lease <= 3; ++lease) {
        const auto job = s.issue(lease, "only", far, alive, policy);
        ASSERT_TRUE(job) << lease;
        if (!first) first = job;
        EXPECT_EQ(job->rect, first->rect);
        ASSERT_TRUE(s.fail_job(lease, "only", "boom", alive, policy));
    }
    EXPECT_EQ(s.state(), RenderState::Failed);
    EXPECT_EQ(s.error(), where(*first) + " failed 3 times on 1 worker: boom");
}

TEST_F(FailingJobsTest, TwoWorkersFailTheRenderOnceNeitherHasAnyoneElseToTry) {
    RenderSession s("r", spec, 0);
    s.start();
    const std::set<std::string> alive{"a", "b"};
    uint64_t lease = 1;
    for (const char* w : {"a", "b", "a"}) {
        ASSERT_TRUE(s.issue(lease, w, far, alive, policy)) << w;
        ASSERT_TRUE(s.fail_job(lease++, w, "boom", alive, policy));
    }
    EXPECT_EQ(s.state(), RenderState::Failed);
    EXPECT_NE(s.error().find("failed 3 times on 2 workers: boom"), std::string::npos)
        << s.error();
}

TEST_F(FailingJobsTest, KIsThePolicys) {
    policy.max_job_failures = 1;
    RenderSession s("r", spec, 0);
    s.start();
    ASSERT_TRUE(s.issue(1, "a", far, {"a", "b"}, policy));
    ASSERT_TRUE(s.fail_job(1, "a", "boom", {"a", "b"}, policy));
    EXPECT_EQ(s.state(), RenderState::Failed);
}

}  // namespace
}  // namespace aliquot
