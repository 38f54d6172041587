#include "cell_batches.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <tuple>
#include <vector>

namespace aliquot {
namespace {

using Sample = std::tuple<uint32_t, uint32_t, uint64_t>;  // x, y, k
using Batch = std::vector<Sample>;

// A round on a whole image of w x h pixels: counts 0-5 times `scale`, first samples 0-4.
SampleJob uneven_round(uint32_t w, uint32_t h, uint32_t scale = 1) {
    SampleJob round;
    round.rect = {0, 0, w, h};
    for (size_t i = 0; i < round.rect.size(); ++i) {
        round.counts.push_back(uint32_t(i * 7 % 6) * scale);
        round.first_sample.push_back(i % 5);
    }
    return round;
}

SampleJob part_of(const SampleJob& round, const PixelRect& rect) {
    SampleJob part;
    part.rect = rect;
    for (uint32_t y = rect.y; y < rect.y + rect.height; ++y)
        for (uint32_t x = rect.x; x < rect.x + rect.width; ++x) {
            const size_t i = size_t(y) * round.rect.width + x;
            part.counts.push_back(round.counts[i]);
            part.first_sample.push_back(round.first_sample[i]);
        }
    return part;
}

// Every batch of a job, in the order its cells and batches come; each lane's pixel
// index checked against its coordinates.
std::vector<Batch> batches_of(const SampleJob& job) {
    std::vector<Batch> out;
    const JobCells cells(job.rect);
    SampleBatch batch;
    for (size_t c = 0; c < cells.count(); ++c)
        for_each_batch(job, cells[c], batch, [&](const SampleBatch& b) {
            Batch lanes;
            for (int j = 0; j < b.count; ++j) {
                const uint32_t x = b.x[j], y = b.y[j];
                EXPECT_EQ(b.pixel[j],
                          size_t(y - job.rect.y) * job.rect.width + (x - job.rect.x));
                lanes.emplace_back(x, y, b.k[j]);
            }
            out.push_back(lanes);
        });
    return out;
}

// The batches of a round cut into square tiles of `tile` pixels from the origin.
std::vector<Batch> batches_cut_at(const SampleJob& round, uint32_t tile) {
    const uint32_t w = round.rect.width, h = round.rect.height;
    std::vector<Batch> all;
    for (uint32_t y0 = 0; y0 < h; y0 += tile)
        for (uint32_t x0 = 0; x0 < w; x0 += tile) {
            const std::vector<Batch> part = batches_of(
                part_of(round, {x0, y0, std::min(tile, w - x0), std::min(tile, h - y0)}));
            all.insert(all.end(), part.begin(), part.end());
        }
    std::sort(all.begin(), all.end());
    return all;
}

TEST(CellBatches, AreTheSameHoweverARoundIsCutOnCells) {
    // 28 x 19: the right and bottom cells are clipped by the image. Up to 5 samples a
    // pixel (a cell is one batch) and up to 50 (a cell is several).
    for (uint32_t scale : {1u, 10u}) {
        const SampleJob round = uneven_round(28, 19, scale);
        const std::vector<Batch> whole = batches_cut_at(round, 32);
        for (uint32_t tile : {8u, 16u, 24u, 40u})
            EXPECT_EQ(batches_cut_at(round, tile), whole) << tile << ", " << scale;
    }
}

TEST(CellBatches, FillEveryLaneWhenEachPixelHasOneSample) {
    SampleJob round = uneven_round(32, 16);
    std::fill(round.counts.begin(), round.counts.end(), 1u);
    std::fill(round.first_sample.begin(), round.first_sample.end(), 0u);
    const std::vector<Batch> batches = batches_of(round);
    // 8 cells of 64 pixels, a batch each: radiance_batch's lanes all busy.
    ASSERT_GE(kCellSide * kCellSide, uint32_t(PathTracer::kBatch));
    ASSERT_EQ(batches.size(), 8u);
    for (const Batch& b : batches) {
        ASSERT_EQ(b.size(), size_t(kCellSide * kCellSide));
        // One cell's pixels in scanline order.
        const auto [x0, y0, k0] = b.front();
        for (size_t j = 0; j < b.size(); ++j)
            EXPECT_EQ(b[j], Sample(x0 + uint32_t(j % 8), y0 + uint32_t(j / 8), 0));
    }
}

TEST(CellBatches, CutACellsSamplesIntoFullBatchesInScanlineOrder) {
    for (uint32_t scale : {1u, 10u, 100u}) {
        const SampleJob round = uneven_round(28, 19, scale);
        const JobCells cells(round.rect);
        SampleBatch batch;
        for (size_t c = 0; c < cells.count(); ++c) {
            std::vector<int> sizes;
            Batch lanes;
            for_each_batch(round, cells[c], batch, [&](const SampleBatch& b) {
                sizes.push_back(b.count);
                for (int j = 0; j < b.count; ++j)
                    lanes.emplace_back(b.x[j], b.y[j], b.k[j]);
            });
            Batch
                expected;  // the cell's pixels row by row, each pixel's samples in order
            const PixelRect& cell = cells[c];
            for (uint32_t y = cell.y; y < cell.y + cell.height; ++y)
                for (uint32_t x = cell.x; x < cell.x + cell.width; ++x) {
                    const size_t i = size_t(y) * 28 + x;
                    for (uint32_t s = 0; s < round.counts[i]; ++s)
                        expected.emplace_back(x, y, round.first_sample[i] + s);
                }
            EXPECT_EQ(lanes, expected);
            for (size_t b = 0; b + 1 < sizes.size(); ++b)
                EXPECT_EQ(sizes[b], SampleBatch::kMax);
            if (scale == 100 && cell.width == kCellSide && cell.height == kCellSide) {
                EXPECT_GT(sizes.size(), 2u);  // many batches
            }
        }
    }
}

TEST(CellBatches, CoverARectangleThatCutsThroughCellsOnce) {
    const SampleJob round = uneven_round(28, 19);
    const SampleJob part = part_of(round, {5, 3, 13, 11});
    std::map<Sample, int> seen;
    for (const Batch& b : batches_of(part))
        for (const Sample& s : b) ++seen[s];
    size_t samples = 0;
    for (uint32_t c : part.counts) samples += c;
    EXPECT_EQ(seen.size(), samples);
    for (const auto& [s, times] : seen) {
        EXPECT_EQ(times, 1);
        const auto [x, y, k] = s;
        EXPECT_TRUE(x >= 5 && x < 18 && y >= 3 && y < 14);
    }
}

TEST(JobCells, ClipTheGridToTheRectangle) {
    const JobCells cells({5, 3, 13, 11});  // x 5..17, y 3..13
    ASSERT_EQ(cells.count(), 6u);          // grid columns 0-2, rows 0-1
    EXPECT_EQ(cells[0], (PixelRect{5, 3, 3, 5}));
    EXPECT_EQ(cells[1], (PixelRect{8, 3, 8, 5}));
    EXPECT_EQ(cells[2], (PixelRect{16, 3, 2, 5}));
    EXPECT_EQ(cells[5], (PixelRect{16, 8, 2, 6}));
    EXPECT_EQ(JobCells({8, 0, 0, 4}).count(), 0u);
}

}  // namespace
}  // namespace aliquot
