#include "round_cutter.h"

#include <gtest/gtest.h>

namespace aliquot {
namespace {

TEST(RoundCutter, JobsCoverEveryPixelWithSamplesExactlyOnce) {
    Accumulator acc(70, 45);
    Round round{0, std::vector<uint32_t>(70 * 45, 4)};
    round.spp[5] = 0;
    std::vector<int> covered(70 * 45, 0);
    for (const SampleJob& job : cut_round(round, acc, 32))
        for (uint32_t y = 0; y < job.rect.height; ++y)
            for (uint32_t x = 0; x < job.rect.width; ++x) {
                const size_t i = size_t(job.rect.y + y) * 70 + job.rect.x + x;
                ++covered[i];
                EXPECT_EQ(job.counts[y * job.rect.width + x], round.spp[i]);
            }
    for (int c : covered) EXPECT_EQ(c, 1);
}

TEST(RoundCutter, SampleIndicesContinueFromWhatEachPixelHas) {
    Accumulator acc(2, 1);
    SampleJobResult r;
    r.rect = {1, 0, 1, 1};
    r.pixels.resize(1);
    r.pixels[0].samples = 7;
    acc.merge(r);
    const auto jobs = cut_round(Round{1, {3, 3}}, acc, 32);
    ASSERT_EQ(jobs.size(), 1u);
    EXPECT_EQ(jobs[0].first_sample[0], 0u);
    EXPECT_EQ(jobs[0].first_sample[1], 7u);
}

TEST(RoundCutter, SkipsTilesWithoutSamples) {
    Accumulator acc(64, 32);
    Round round{0, std::vector<uint32_t>(64 * 32, 0)};
    round.spp[40] = 1;  // only the right-hand 32x32 tile has work
    const auto jobs = cut_round(round, acc, 32);
    ASSERT_EQ(jobs.size(), 1u);
    EXPECT_EQ(jobs[0].rect.x, 32u);
}

TEST(RoundCutter, LastQuarterOfTheRoundIsCutIntoQuadrants) {
    Accumulator acc(128, 128);
    const Round round{0, std::vector<uint32_t>(128 * 128, 2)};
    const auto jobs = cut_round(round, acc, 32);  // 16 tiles: 12 whole, 4 in quadrants
    ASSERT_EQ(jobs.size(), 12u + 16u);
    for (size_t j = 0; j < jobs.size(); ++j)
        EXPECT_EQ(jobs[j].rect.width, j < 12 ? 32u : 16u) << "job " << j;
    uint64_t samples = 0;
    for (const SampleJob& job : jobs)
        for (uint32_t c : job.counts) samples += c;
    EXPECT_EQ(samples, 2u * 128 * 128);
}

TEST(RoundCutter, SmallImagesGetEnoughJobsForSeveralWorkers) {
    Accumulator acc(256, 256);
    const auto jobs = cut_round(Round{0, std::vector<uint32_t>(256 * 256, 1)}, acc);
    // job_tile_side(1) is 128, which would leave 4 jobs: halved to 64 (16 tiles).
    EXPECT_EQ(jobs.front().rect.width, 64u);
    EXPECT_EQ(jobs.size(), 12u + 16u);
}

// The previous round's jobs lend their vectors, larger and smaller than needed and full
// of stale values: the jobs cut into them are the jobs cut into fresh ones.
TEST(RoundCutter, JobsCutIntoSpareJobsAreTheJobsCutAfresh) {
    Accumulator acc(160, 96);
    Round round{3, std::vector<uint32_t>(160 * 96)};
    for (size_t i = 0; i < round.spp.size(); ++i) round.spp[i] = uint32_t(i % 7);
    std::vector<SampleJob> spare(5);
    for (size_t k = 0; k < spare.size(); ++k) {
        spare[k].rect = {1, 2, 3, 4};
        spare[k].counts.assign(k % 2 ? 5000 : 3, 99);
        spare[k].first_sample.assign(k % 2 ? 5000 : 3, 12345);
    }
    const std::vector<SampleJob> fresh = cut_round(round, acc, 32);
    const std::vector<SampleJob> reused = cut_round(round, acc, 32, std::move(spare));
    ASSERT_EQ(reused.size(), fresh.size());
    for (size_t j = 0; j < fresh.size(); ++j) {
        EXPECT_EQ(reused[j].rect, fresh[j].rect) << "job " << j;
        EXPECT_EQ(reused[j].counts, fresh[j].counts) << "job " << j;
        EXPECT_EQ(reused[j].first_sample, fresh[j].first_sample) << "job " << j;
    }
}

// The largest power-of-two side up to 128 whose tile holds at most kJobSamples (2^18).
TEST(RoundCutter, TilesHoldAboutAQuarterMillionSamplesUpTo128) {
    EXPECT_EQ(job_tile_side(1), 128u);
    EXPECT_EQ(job_tile_side(16), 128u);  // exactly 2^18
    EXPECT_EQ(job_tile_side(17), 64u);
    EXPECT_EQ(job_tile_side(64), 64u);
    EXPECT_EQ(job_tile_side(128), 32u);
    EXPECT_EQ(job_tile_side(1000), 16u);
    EXPECT_EQ(job_tile_side(1e6), 16u);  // never below kMinAutoTile
}

}  // namespace
}  // namespace aliquot
