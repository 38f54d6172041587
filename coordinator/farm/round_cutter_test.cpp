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
    EXPECT_EQ(jobs[0].rect.x, 40u);  // and only its cell (40, 0) to (47, 7)
}

TEST(RoundCutter, ATileIsCutDownToTheCellsThatHoldSamples) {
    // A 100x70 image in 64x64 tiles: samples at (9, 3) and (20, 30) of the first tile,
    // and at (99, 69), the last pixel, in the last. Each job covers the cells (8x8 on
    // the image's grid) from its first sample's to its last's, clipped at the image.
    Accumulator acc(100, 70);
    Round round{0, std::vector<uint32_t>(100 * 70, 0)};
    round.spp[3 * 100 + 9] = 2;
    round.spp[30 * 100 + 20] = 3;
    round.spp[69 * 100 + 99] = 1;
    const std::vector<PixelRect> rects = round_tiles(round, 100, 70, 64, 1);
    ASSERT_EQ(rects.size(), 2u);
    EXPECT_EQ(rects[0], (PixelRect{8, 0, 16, 32}));  // cells x 8-23, y 0-31
    EXPECT_EQ(rects[1], (PixelRect{96, 64, 4, 6}));  // its last cell, clipped
    uint64_t samples = 0;
    for (const SampleJob& job : cut_round(round, acc, 64))
        for (uint32_t c : job.counts) samples += c;
    EXPECT_EQ(samples, 6u);
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
    const std::vector<PixelRect> rects = round_tiles(round, 160, 96, 32);
    ASSERT_EQ(rects.size(), fresh.size());
    ASSERT_GT(rects.size(), spare.size());
    std::vector<SampleJob> reused;
    for (size_t j = 0; j < rects.size(); ++j)
        reused.push_back(cut_job(rects[j], round, acc,
                                 j < spare.size() ? std::move(spare[j]) : SampleJob{}));
    for (size_t j = 0; j < fresh.size(); ++j) {
        EXPECT_EQ(reused[j].rect, fresh[j].rect) << "job " << j;
        EXPECT_EQ(reused[j].counts, fresh[j].counts) << "job " << j;
        EXPECT_EQ(reused[j].first_sample, fresh[j].first_sample) << "job " << j;
    }
}

// round_tiles against its definition, written out plainly: the tiles that hold samples,
// row by row, the last quarter of them as their quadrants that hold samples; and each
// job cut alone is the job cut_round cuts.
TEST(RoundCutter, RoundTilesAreTheTilesWithSamplesAndTheTailsQuadrants) {
    for (const uint32_t tile : {0u, 16u, 20u, 32u, 33u, 64u}) {
        for (const auto& [w, h] :
             {std::pair{157u, 93u}, std::pair{64u, 64u}, std::pair{31u, 200u}}) {
            SCOPED_TRACE(std::to_string(tile) + " " + std::to_string(w) + "x" +
                         std::to_string(h));
            Accumulator acc(w, h);
            Round round{0, std::vector<uint32_t>(size_t(w) * h, 0)};
            for (size_t i = 0; i < round.spp.size(); ++i)  // sparse, as a steered round
                round.spp[i] = (i * 2654435761u) % 97 < 3 ? uint32_t(1 + i % 5) : 0;
            const auto holds = [&](const PixelRect& r) {
                for (uint32_t y = r.y; y < r.y + r.height; ++y)
                    for (uint32_t x = r.x; x < r.x + r.width; ++x)
                        if (round.spp[size_t(y) * w + x]) return true;
                return false;
            };
            const std::vector<SampleJob> jobs = cut_round(round, acc, tile);
            ASSERT_FALSE(jobs.empty());
            // The side cut_round chose: the first job's, unless it was a quadrant; an
            // explicit one rounded up to whole cells.
            const uint32_t side =
                tile ? (tile + kCellSide - 1) / kCellSide * kCellSide
                     : std::max(jobs.front().rect.width, jobs.front().rect.height);
            std::vector<PixelRect> tiles, want;
            for (uint32_t y = 0; y < h; y += side)
                for (uint32_t x = 0; x < w; x += side) {
                    const PixelRect r{x, y, std::min(side, w - x), std::min(side, h - y)};
                    if (holds(r)) tiles.push_back(r);
                }
            const size_t whole =
                side < 2 * kMinAutoTile ? tiles.size() : tiles.size() - tiles.size() / 4;
            want.assign(tiles.begin(), tiles.begin() + whole);
            for (size_t k = whole; k < tiles.size(); ++k) {
                const PixelRect& r = tiles[k];
                // Halved at the first cell boundary at or after the middle.
                const auto half = [](uint32_t n) {
                    const uint32_t cells = (n + 2 * kCellSide - 1) / (2 * kCellSide);
                    return std::min(n, cells * kCellSide);
                };
                const uint32_t hw = half(r.width), hh = half(r.height);
                for (const PixelRect& q :
                     {PixelRect{r.x, r.y, hw, hh},
                      PixelRect{r.x + hw, r.y, r.width - hw, hh},
                      PixelRect{r.x, r.y + hh, hw, r.height - hh},
                      PixelRect{r.x + hw, r.y + hh, r.width - hw, r.height - hh}})
                    if (q.width && q.height && holds(q)) want.push_back(q);
            }
            const std::vector<PixelRect> got = round_tiles(round, w, h, tile);
            ASSERT_EQ(got.size(), want.size());
            ASSERT_EQ(jobs.size(), want.size());
            for (size_t k = 0; k < want.size(); ++k) {
                EXPECT_EQ(got[k], want[k]) << k;
                const SampleJob alone = cut_job(got[k], round, acc);
                EXPECT_EQ(alone.rect, jobs[k].rect);
                EXPECT_EQ(alone.counts, jobs[k].counts);
                EXPECT_EQ(alone.first_sample, jobs[k].first_sample);
            }
        }
    }
}

// The tracer batches samples by cells (kCellSide), so a round cut on cells traces the
// same bits however it is cut: every job's rectangle starts on a cell boundary and ends
// on one or at the image's edge, whatever tile is asked for, quadrants included.
TEST(RoundCutter, EveryJobIsCutOnTheCellGrid) {
    for (const uint32_t tile : {0u, 1u, 5u, 8u, 12u, 16u, 33u, 40u, 64u, 100u}) {
        for (const auto& [w, h] :
             {std::pair{157u, 93u}, std::pair{31u, 200u}, std::pair{8u, 8u},
              std::pair{7u, 3u}, std::pair{1920u, 1080u}}) {
            SCOPED_TRACE(std::to_string(tile) + " " + std::to_string(w) + "x" +
                         std::to_string(h));
            const Round round{0, std::vector<uint32_t>(size_t(w) * h, 1)};
            size_t pixels = 0;
            for (const PixelRect& r : round_tiles(round, w, h, tile)) {
                EXPECT_EQ(r.x % kCellSide, 0u);
                EXPECT_EQ(r.y % kCellSide, 0u);
                EXPECT_TRUE((r.x + r.width) % kCellSide == 0 || r.x + r.width == w);
                EXPECT_TRUE((r.y + r.height) % kCellSide == 0 || r.y + r.height == h);
                pixels += r.size();
            }
            EXPECT_EQ(pixels, size_t(w) * h);
        }
    }
}

// Quadrants split at a cell boundary: a tile of 40 in 24 and 16, one of 20 (clipped by
// the image) in 16 and 4.
TEST(RoundCutter, QuadrantsAreHalvedOnCells) {
    // 160x40 in tiles of 40: 4 tiles, the last one in quadrants.
    const Round wide{0, std::vector<uint32_t>(160 * 40, 1)};
    std::vector<PixelRect> got = round_tiles(wide, 160, 40, 40);
    ASSERT_EQ(got.size(), 3u + 4u);
    EXPECT_EQ(got[3], (PixelRect{120, 0, 24, 24}));
    EXPECT_EQ(got[4], (PixelRect{144, 0, 16, 24}));
    EXPECT_EQ(got[5], (PixelRect{120, 24, 24, 16}));
    EXPECT_EQ(got[6], (PixelRect{144, 24, 16, 16}));
    const Round clipped{0, std::vector<uint32_t>(size_t(140) * 40, 1)};
    got = round_tiles(clipped, 140, 40, 40);  // the last tile is 20 wide
    ASSERT_EQ(got.size(), 3u + 4u);
    EXPECT_EQ(got[3], (PixelRect{120, 0, 16, 24}));
    EXPECT_EQ(got[4], (PixelRect{136, 0, 4, 24}));
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

// The round after the one out, cut while some of the round out's jobs have not merged:
// each job is the one cut once all of them have.
TEST(RoundCutter, AJobOfTheRoundAfterIsTheSameCutBeforeOrAfterTheRoundOutMerges) {
    const uint32_t w = 37, h = 29;
    Accumulator acc(w, h);
    Round out{0, std::vector<uint32_t>(size_t(w) * h)}, after{1, out.spp};
    for (size_t i = 0; i < out.spp.size(); ++i) {
        out.spp[i] = uint32_t(i * 7 % 5);  // some pixels get nothing this round
        after.spp[i] = uint32_t(1 + i % 3);
    }
    const std::vector<SampleJob> out_jobs = cut_round(out, acc, 8);
    const auto merge = [&](Accumulator& into, const SampleJob& job) {
        SampleJobResult r;
        r.rect = job.rect;
        r.pixels.resize(job.rect.size());
        for (size_t k = 0; k < r.pixels.size(); ++k) r.pixels[k].samples = job.counts[k];
        into.merge(r);
    };
    Accumulator all;
    all.copy_from(acc);
    for (const SampleJob& job : out_jobs) merge(all, job);
    // Every other job of the round out merged; the rest are still traced.
    Accumulator part;
    part.copy_from(acc);
    std::vector<const SampleJob*> unmerged;
    for (size_t k = 0; k < out_jobs.size(); ++k)
        if (k % 2)
            unmerged.push_back(&out_jobs[k]);
        else
            merge(part, out_jobs[k]);
    ASSERT_FALSE(unmerged.empty());
    for (const PixelRect& rect : round_tiles(after, w, h, 11)) {  // across the old tiles
        const SampleJob early = cut_job_after(rect, after.spp, part, unmerged);
        const SampleJob late = cut_job(rect, after, all);
        EXPECT_EQ(early.counts, late.counts);
        EXPECT_EQ(early.first_sample, late.first_sample);
    }
}

// Every pixel with samples in exactly one job, each job on the cell grid: what a cut may
// change without changing a bit of the image.
void expect_cut_on_cells_covering(const std::vector<PixelRect>& rects,
                                  const std::vector<uint32_t>& spp, uint32_t w) {
    std::vector<int> covered(spp.size(), 0);
    for (const PixelRect& r : rects) {
        EXPECT_EQ(r.x % kCellSide, 0u);
        EXPECT_EQ(r.y % kCellSide, 0u);
        for (uint32_t y = r.y; y < r.y + r.height; ++y)
            for (uint32_t x = r.x; x < r.x + r.width; ++x) ++covered[size_t(y) * w + x];
    }
    for (size_t i = 0; i < spp.size(); ++i)
        if (spp[i]) ASSERT_EQ(covered[i], 1) << i;
}

// A farm of 256 worker cores at 1920x1080: a round of 2 spp (tiles of 128, 135 of them)
// is cut finer, into at least two jobs a core.
TEST(RoundCutter, ARoundHasAtLeastTwoJobsAWorkerCore) {
    const uint32_t w = 1920, h = 1080;
    const std::vector<uint32_t> spp(size_t(w) * h, 2);
    ASSERT_LT(round_tiles(spp, w, h).size(), 512u);
    for (const size_t cores : {1u, 8u, 64u, 256u}) {
        const std::vector<PixelRect> rects =
            round_tiles(spp, w, h, 0, min_jobs_for_cores(cores));
        EXPECT_GE(rects.size(), 2 * cores) << cores << " cores";
        expect_cut_on_cells_covering(rects, spp, w);
    }
    EXPECT_EQ(min_jobs_for_cores(3), kMinJobsPerRound);  // never fewer than before
}

// A steered round that refines a small area skips most tiles: the count of the image's
// tiles says 16 are enough, the jobs it leaves are two. Smaller tiles until there are
// enough jobs, down to kMinAutoTile.
TEST(RoundCutter, ARoundOnASmallAreaIsCutIntoEnoughJobs) {
    const uint32_t w = 512, h = 512;
    std::vector<uint32_t> spp(size_t(w) * h, 0);
    for (uint32_t y = 200; y < 296; ++y)
        for (uint32_t x = 100; x < 196; ++x) spp[size_t(y) * w + x] = 4;
    const std::vector<PixelRect> rects = round_tiles(spp, w, h, 0, min_jobs_for_cores(8));
    EXPECT_GE(rects.size(), 16u);
    expect_cut_on_cells_covering(rects, spp, w);
    // 64 cores want 128 jobs; the area holds 49 tiles of 16, the least side cut to.
    const std::vector<PixelRect> finest =
        round_tiles(spp, w, h, 0, min_jobs_for_cores(64));
    for (const PixelRect& r : finest) EXPECT_LE(r.width, kMinAutoTile);
    expect_cut_on_cells_covering(finest, spp, w);
    // An explicit tile is kept whatever the farm.
    EXPECT_EQ(round_tiles(spp, w, h, 64, min_jobs_for_cores(64)),
              round_tiles(spp, w, h, 64));
}

}  // namespace
}  // namespace aliquot
