// Issue 33: merges of one render's disjoint jobs add their sums off the render's lock, at
// once; the render's lock is held only to check the lease and to count the merge.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <thread>

#include "coordinator.h"
#include "farm_test_results.h"
#include "scene_loader.h"

namespace aliquot {
namespace {

using std::chrono::milliseconds;

uint64_t samples_of(const LeaseGrant& grant) {
    uint64_t n = 0;
    for (const uint32_t c : grant.job.counts) n += c;
    return n;
}

// The samples an image's "sampleCount.Y" layer shows.
uint64_t samples_shown(const Image& image) {
    for (const Image::Channel& ch : image.extra)
        if (ch.name == "sampleCount.Y") {
            double shown = 0;
            for (const float v : ch.values) shown += v;
            return uint64_t(shown);
        }
    return 0;
}

// A render of 64x64 uniform pixels with one merge of its first job held mid-add.
struct OneMergeHeld {
    Coordinator c{CoordinatorOptions{}};
    std::string id = c.submit(square_test_spec("uniform", 64, 4));
    std::string a = c.register_worker("a", 8).session;
    std::optional<LeaseGrant> ga = c.lease(a, milliseconds(0));
    HeldAdd held;
    std::future<CompleteStatus> merge;

    // Starts the merge and returns once it is held.
    void start() {
        c.set_while_adding_for_test(id, held.hook());
        merge = std::async(std::launch::async, [this] {
            return c.complete(a, ga->lease_id, made_up_result(*ga)).status;
        });
        held.reached.get_future().wait();
    }
    // Lets the merge go once `call` has ended or a moment has passed (with adds waited
    // for, the call cannot end first: a moment too short only makes a test weaker).
    template <class T>
    void release_after(std::future<T>& call) {
        call.wait_for(milliseconds(300));
        held.release.set_value();
    }
};

// Two merges of one render at once: one held mid-merge (between its check and its add)
// while a second job of the same round completes and is counted. With the add under
// the render's lock, the second waited for the first.
TEST(ParallelMerges, TwoMergesOfOneRenderProceedAtOnce) {
    Coordinator c(CoordinatorOptions{});
    const std::string id = c.submit(square_test_spec("uniform", 64, 4));
    const std::string a = c.register_worker("a", 8).session;
    const std::string b = c.register_worker("b", 8).session;
    const std::optional<LeaseGrant> ga = c.lease(a, milliseconds(0));
    const std::optional<LeaseGrant> gb = c.lease(b, milliseconds(0));
    ASSERT_TRUE(ga && gb);
    ASSERT_FALSE(ga->job.rect == gb->job.rect);
    HeldAdd held;
    c.set_while_adding_for_test(id, held.hook());
    auto first = std::async(std::launch::async, [&] {
        return c.complete(a, ga->lease_id, made_up_result(*ga)).status;
    });
    held.reached.get_future().wait();
    auto second = std::async(std::launch::async, [&] {
        return c.complete(b, gb->lease_id, made_up_result(*gb)).status;
    });
    // Not a time limit on the merge: only so a regression fails rather than hangs.
    const bool second_ended =
        second.wait_for(std::chrono::seconds(20)) == std::future_status::ready;
    EXPECT_TRUE(second_ended) << "the second merge waited for the first";
    if (second_ended) {
        EXPECT_EQ(second.get(), CompleteStatus::Merged);
        // Counted while the first is still being added.
        EXPECT_EQ(c.info(id)->samples_done, samples_of(*gb));
    }
    held.release.set_value();
    EXPECT_EQ(first.get(), CompleteStatus::Merged);
    EXPECT_EQ(c.info(id)->samples_done, samples_of(*ga) + samples_of(*gb));
    EXPECT_EQ(c.info(id)->state, RenderState::Running);
}

// A render cancelled while one of its merges is mid-add ends with that merge whole: the
// cancel waits for the add, so the render's end (its samples, the image written from its
// buffers) does not change after it.
TEST(ParallelMerges, ACancelDuringAMergeWaitsForItsAdd) {
    OneMergeHeld m;
    ASSERT_TRUE(m.ga);
    m.start();
    auto cancel = std::async(std::launch::async, [&] { return m.c.cancel(m.id); });
    m.release_after(cancel);
    const std::optional<RenderInfo> ended = cancel.get();
    ASSERT_TRUE(ended);
    EXPECT_EQ(ended->state, RenderState::Cancelled);
    EXPECT_EQ(m.merge.get(), CompleteStatus::Merged);
    EXPECT_EQ(ended->samples_done, samples_of(*m.ga));
    // The image holds exactly the samples the ended render counts.
    EXPECT_EQ(samples_shown(*m.c.image(m.id, true)), samples_of(*m.ga));
}

// An image read while a merge is mid-add waits for the add: a preview never shows half
// a result, nor a render's samples without the sums they came with.
TEST(ParallelMerges, AnImageReadDuringAMergeWaitsForItsAdd) {
    OneMergeHeld m;
    ASSERT_TRUE(m.ga);
    m.start();
    auto read = std::async(std::launch::async, [&] { return *m.c.image(m.id, true); });
    m.release_after(read);
    EXPECT_EQ(samples_shown(read.get()), samples_of(*m.ga));
    EXPECT_EQ(m.merge.get(), CompleteStatus::Merged);
}

// A result refused off the lock while another merge of the render is mid-add: rejected,
// nothing of it added, its job traced again; the render ends as one worker alone.
TEST(ParallelMerges, AResultRefusedBesideAnotherMergeIsTracedAgain) {
    const RenderSpec spec = square_test_spec("uniform", 64, 4);
    const Image alone = rendered_alone(spec);
    Coordinator c(CoordinatorOptions{});
    const std::string id = c.submit(spec);
    const std::string a = c.register_worker("a", 8).session;
    const std::string b = c.register_worker("b", 8).session;
    const std::optional<LeaseGrant> ga = c.lease(a, milliseconds(0));
    const std::optional<LeaseGrant> gb = c.lease(b, milliseconds(0));
    ASSERT_TRUE(ga && gb);
    HeldAdd held;
    c.set_while_adding_for_test(id, held.hook());
    auto first = std::async(std::launch::async, [&] {
        return c.complete(a, ga->lease_id, made_up_result(*ga)).status;
    });
    held.reached.get_future().wait();
    SampleJobResult bad = made_up_result(*gb);
    bad.pixels.back().samples += 1;  // not what its job asked for
    const CompleteOutcome refused = c.complete(b, gb->lease_id, std::move(bad));
    EXPECT_EQ(refused.status, CompleteStatus::Rejected);
    EXPECT_NE(refused.message.find("job asked for"), std::string::npos)
        << refused.message;
    held.release.set_value();
    EXPECT_EQ(first.get(), CompleteStatus::Merged);
    EXPECT_EQ(c.info(id)->samples_done, samples_of(*ga));
    const std::string w = c.register_worker("w", 1).session;
    while (!is_terminal(c.info(id)->state))
        if (auto grant = c.lease(w, milliseconds(20)))
            c.complete(w, grant->lease_id, made_up_result(*grant));
    ASSERT_EQ(c.info(id)->state, RenderState::Done);
    const Image together = *c.image(id, true);
    EXPECT_EQ(together.rgb, alone.rgb);
    ASSERT_EQ(together.extra.size(), alone.extra.size());
    for (size_t e = 0; e < alone.extra.size(); ++e)
        EXPECT_EQ(together.extra[e].values, alone.extra[e].values);
}

// Many workers merging one render's jobs at once, rounds planned ahead and results held
// for the round after included: the render's bytes are those of one worker alone.
TEST(ParallelMerges, ManyWorkersOnOneRenderEndAsOneWorkerAlone) {
    for (const char* method : {"uniform", "optimal", "adaptive"}) {
        const RenderSpec spec = square_test_spec(method, 96, 16);
        const Image alone = rendered_alone(spec);
        Coordinator c(CoordinatorOptions{});
        const std::string id = c.submit(spec);
        std::vector<std::thread> threads;
        for (int w = 0; w < 6; ++w)
            threads.emplace_back([&, w] {
                const std::string session =
                    c.register_worker("w" + std::to_string(w), 4).session;
                while (!is_terminal(c.info(id)->state)) {
                    const std::optional<LeaseGrant> grant =
                        c.lease(session, milliseconds(20));
                    if (!grant) continue;
                    SampleJobResult result = made_up_result(*grant);
                    c.complete(session, grant->lease_id, std::move(result));
                    if (w == 0) (void)c.image(id, false);  // a reader among the merges
                }
            });
        for (std::thread& t : threads) t.join();
        ASSERT_EQ(c.info(id)->state, RenderState::Done) << method;
        const Image together = *c.image(id, true);
        EXPECT_EQ(together.rgb, alone.rgb) << method;
        ASSERT_EQ(together.extra.size(), alone.extra.size()) << method;
        for (size_t e = 0; e < alone.extra.size(); ++e)
            EXPECT_EQ(together.extra[e].values, alone.extra[e].values) << method;
    }
}

}  // namespace
}  // namespace aliquot
