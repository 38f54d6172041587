#include "trace_job.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <limits>

#include "scene_loader.h"

namespace aliquot {
namespace {

SampleJob whole_image_job(uint32_t w, uint32_t h, uint32_t spp, uint64_t first = 0) {
    SampleJob job;
    job.rect = {0, 0, w, h};
    job.counts.assign(job.rect.size(), spp);
    job.first_sample.assign(job.rect.size(), first);
    return job;
}

bool same_bits(const PixelSums& a, const PixelSums& b) {
    return std::memcmp(a.even, b.even, sizeof a.even) == 0 &&
           std::memcmp(a.odd, b.odd, sizeof a.odd) == 0 &&
           std::memcmp(&a.sum_sq_luminance, &b.sum_sq_luminance, sizeof(double)) == 0 &&
           a.samples == b.samples && a.rays == b.rays && a.nonfinite == b.nonfinite;
}

class SampleJobTest : public ::testing::Test {
protected:
    Scene scene = load_scene("cornell-box");
    PathTracer tracer{scene};
    RenderGeometry geometry{24, 16, 5};
};

TEST_F(SampleJobTest, ResultDoesNotDependOnThreadCount) {
    SampleJob job = whole_image_job(24, 16, 4);
    for (size_t i = 0; i < job.counts.size(); ++i) job.counts[i] = uint32_t(i % 5);
    const SampleJobResult one = trace_sample_job(tracer, geometry, job, 1);
    const SampleJobResult two = trace_sample_job(tracer, geometry, job, 2);
    for (size_t i = 0; i < one.pixels.size(); ++i)
        ASSERT_TRUE(same_bits(one.pixels[i], two.pixels[i]));
}

// The part of `whole` (a job over the whole image) inside `rect`.
SampleJob part_of(const SampleJob& whole, uint32_t image_width, const PixelRect& rect) {
    SampleJob part;
    part.rect = rect;
    for (uint32_t y = rect.y; y < rect.y + rect.height; ++y)
        for (uint32_t x = rect.x; x < rect.x + rect.width; ++x) {
            part.counts.push_back(whole.counts[size_t(y) * image_width + x]);
            part.first_sample.push_back(whole.first_sample[size_t(y) * image_width + x]);
        }
    return part;
}

// A round of 0-5 samples a pixel (so a cell's batches run across pixels, and a pixel's
// samples across batches) on an image whose right and bottom cells are clipped, cut into
// jobs at several tile sides on the cell grid (as round_cutter cuts) and traced with 1
// and 2 threads: every cut gives the whole job's bytes.
TEST_F(SampleJobTest, ResultDoesNotDependOnHowPixelsAreCut) {
    const uint32_t w = 28, h = 19;
    const RenderGeometry odd{w, h, 5};
    SampleJob round = whole_image_job(w, h, 0);
    for (size_t i = 0; i < round.counts.size(); ++i) {
        round.counts[i] = uint32_t(i * 7 % 6);
        round.first_sample[i] = i % 5;
    }
    const SampleJobResult whole = trace_sample_job(tracer, odd, round, 1);
    for (uint32_t tile : {8u, 16u, 24u}) {
        for (int threads : {1, 2}) {
            for (uint32_t y0 = 0; y0 < h; y0 += tile) {
                for (uint32_t x0 = 0; x0 < w; x0 += tile) {
                    const PixelRect rect{x0, y0, std::min(tile, w - x0),
                                         std::min(tile, h - y0)};
                    const SampleJobResult cut =
                        trace_sample_job(tracer, odd, part_of(round, w, rect), threads);
                    for (uint32_t y = 0; y < rect.height; ++y)
                        for (uint32_t x = 0; x < rect.width; ++x)
                            ASSERT_TRUE(
                                same_bits(cut.pixels[size_t(y) * rect.width + x],
                                          whole.pixels[size_t(y0 + y) * w + x0 + x]))
                                << "tile " << tile << ", threads " << threads
                                << ", pixel " << x0 + x << "," << y0 + y;
                }
            }
        }
    }
}

// A rectangle that cuts through cells (a job from the network may be any) is traced
// correctly: each pixel gets its samples, and its radiance is that of the same samples
// traced in a cut on cells, up to the last bits Embree's packets may change.
TEST_F(SampleJobTest, TracesARectangleThatCutsThroughCells) {
    const SampleJobResult whole =
        trace_sample_job(tracer, geometry, whole_image_job(24, 16, 3));
    SampleJob part;
    part.rect = {5, 7, 6, 4};
    part.counts.assign(part.rect.size(), 3);
    part.first_sample.assign(part.rect.size(), 0);
    const SampleJobResult cut = trace_sample_job(tracer, geometry, part, 2);
    for (uint32_t row = 0; row < 4; ++row)
        for (uint32_t col = 0; col < 6; ++col) {
            const PixelSums& a = cut.pixels[row * 6 + col];
            const PixelSums& b = whole.pixels[(7 + row) * 24 + 5 + col];
            ASSERT_EQ(a.samples, 3u);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(a.even[c], b.even[c], 1e-4 * (1 + b.even[c]));
                EXPECT_NEAR(a.odd[c], b.odd[c], 1e-4 * (1 + b.odd[c]));
            }
        }
}

TEST_F(SampleJobTest, SplitsSamplesByParityOfTheirIndex) {
    // Samples 0..3 of one pixel: 0 and 2 are even. Starting at 1 instead shifts the
    // parity.
    SampleJob job = whole_image_job(24, 16, 0);
    job.counts[0] = 4;
    const PixelSums from0 = trace_sample_job(tracer, geometry, job).pixels[0];
    SampleJob single = whole_image_job(24, 16, 0);
    single.counts[0] = 1;
    const PixelSums s0 = trace_sample_job(tracer, geometry, single).pixels[0];
    single.first_sample[0] = 2;
    const PixelSums s2 = trace_sample_job(tracer, geometry, single).pixels[0];
    EXPECT_DOUBLE_EQ(from0.even[0], s0.even[0] + s2.even[0]);
    EXPECT_EQ(from0.samples, 4u);
}

TEST_F(SampleJobTest, DifferentSeedGivesDifferentSums) {
    const SampleJob job = whole_image_job(24, 16, 2);
    const SampleJobResult a = trace_sample_job(tracer, geometry, job);
    const SampleJobResult b = trace_sample_job(tracer, {24, 16, 6}, job);
    size_t differing = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i)
        differing += !same_bits(a.pixels[i], b.pixels[i]);
    EXPECT_GT(differing, a.pixels.size() / 2);
}

// A worker told to stop gives the lease back: the job throws JobCancelled, also when its
// one cell holds many batches, and also with several threads.
TEST_F(SampleJobTest, StopsWhenCancelled) {
    const std::atomic<bool> cancel{true};
    SampleJob one_cell;
    one_cell.rect = {8, 8, 8, 8};
    one_cell.counts.assign(one_cell.rect.size(), 1000);
    one_cell.first_sample.assign(one_cell.rect.size(), 0);
    for (int threads : {1, 2})
        EXPECT_THROW(trace_sample_job(tracer, geometry, one_cell, threads, &cancel),
                     JobCancelled);
    EXPECT_THROW(
        trace_sample_job(tracer, geometry, whole_image_job(24, 16, 1), 2, &cancel),
        JobCancelled);
}

TEST_F(SampleJobTest, RejectsJobsThatDoNotFitTheImage) {
    SampleJob job = whole_image_job(25, 16, 1);
    EXPECT_THROW(trace_sample_job(tracer, geometry, job), std::invalid_argument);
    job = whole_image_job(24, 16, 1);
    job.counts.pop_back();
    EXPECT_THROW(trace_sample_job(tracer, geometry, job), std::invalid_argument);
}

TEST(AddSample, DropsNonFiniteRadianceButCountsIt) {
    PixelSums sums;
    add_sample(sums, 0, {1, 2, 3}, 4);
    add_sample(sums, 1, {std::numeric_limits<float>::quiet_NaN(), 0, 0}, 3);
    add_sample(sums, 2, {std::numeric_limits<float>::infinity(), 0, 0}, 2);
    EXPECT_EQ(sums.samples, 3u);
    EXPECT_EQ(sums.nonfinite, 2u);
    EXPECT_EQ(sums.rays, 9u);
    EXPECT_DOUBLE_EQ(sums.even[0], 1.0);
    EXPECT_DOUBLE_EQ(sums.odd[0], 0.0);
    EXPECT_TRUE(std::isfinite(sums.sum_sq_luminance));
}

}  // namespace
}  // namespace aliquot
