// A result whose sums are read where the message holds them (the gRPC service's: wire.h's
// from_proto_in_place) merges from there; one held for the round ahead outlives the
// message, so it must own its sums.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <utility>
#include <vector>

#include "farm_test_results.h"
#include "render_session.h"

namespace aliquot {
namespace {

// What a worker's message holds for `job`: each pixel's samples as asked, half their
// count in red.
std::vector<PixelSums> message_for(const SampleJob& job) {
    std::vector<PixelSums> sums(job.rect.size());
    for (size_t i = 0; i < sums.size(); ++i) {
        sums[i].samples = job.counts[i];
        sums[i].even[0] = 0.5 * double(job.counts[i]);
    }
    return sums;
}

TEST(BorrowedResults, AResultHeldForTheRoundAheadOwnsItsSumsOnceItsMessageIsGone) {
    // Enough samples a pixel for two rounds (the first holds kFirstRoundSamples), the
    // second opened ahead once every job of the first is out.
    RenderSpec spec = small_test_spec();
    spec.width = spec.height = 64;
    spec.strategy.spp = 4096;
    RenderSession s("r", spec, 0);
    s.start();
    const auto far = RenderSession::Clock::now() + std::chrono::hours(1);
    struct Out {
        uint64_t lease;
        SampleJob job;
    };
    // Every job of the first round, then the round ahead's once its plan is made (off
    // this thread), up to its bound: the last is the round ahead's.
    std::vector<Out> out;
    uint64_t lease = 1;
    for (int spin = 0; spin < 100; ++spin) {
        while (auto job = s.issue(lease, "w", far)) out.push_back({lease++, *job});
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ASSERT_GE(out.size(), 2u);
    const Out ahead = out.back();
    out.pop_back();

    uint64_t samples = 0;
    for (const uint32_t c : ahead.job.counts) samples += c;
    {
        std::vector<PixelSums> message = message_for(ahead.job);
        SampleJobResult borrowed;
        borrowed.rect = ahead.job.rect;
        borrowed.pixels.borrow(message.data(), message.size());
        EXPECT_EQ(s.complete(ahead.lease, "w", std::as_const(borrowed)).status,
                  CompleteStatus::Merged);
        ASSERT_EQ(s.merged().total_samples(), 0u);  // the round ahead's: held
        // The message is reused for something else, then freed.
        for (PixelSums& p : message) p = {{9e29, 0, 0}, {0, 0, 0}, 0, 1, 0, 0};
    }
    for (const Out& o : out) {
        for (const uint32_t c : o.job.counts) samples += c;
        SampleJobResult owned;
        owned.rect = o.job.rect;
        const std::vector<PixelSums> sums = message_for(o.job);
        owned.pixels.assign(sums.begin(), sums.end());
        ASSERT_EQ(s.complete(o.lease, "w", std::move(owned)).status,
                  CompleteStatus::Merged);
    }
    // The round out has ended and the held result merged: with the sums it was sent.
    ASSERT_GE(s.rounds_done(), 1u);
    EXPECT_EQ(s.merged().total_samples(), samples);
    const Image image = s.merged().image();
    for (const float v : image.rgb) EXPECT_LE(v, 1.0f);
}

}  // namespace
}  // namespace aliquot
