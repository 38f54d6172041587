// How a job's samples are cut into the tracer's batches: by cells of the image's grid
// (kCellSide in sample_job.h), each cell's samples of the round in scanline order (pixel
// by pixel, each pixel's samples in index order) cut into batches of SampleBatch::kMax
// from the cell's start, each traced by one call of PathTracer::radiance_batch (its
// PathTracer::kBatch lanes refilled from the batch as paths end). So a batch's
// composition, and the order its paths take the lanes, follow from the round and the grid
// alone, never from how the round is cut into jobs on cells or a job among threads; and
// the lanes are full whether the cell's pixels get one sample each or 64.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

#include "path_tracer.h"
#include "sample_job.h"

namespace aliquot {

// A job's pixels in cells: the cells of the grid its rectangle meets, each clipped to the
// rectangle (so to the image), row by row. A rectangle cut on cell boundaries holds whole
// cells (clipped only at the image's edges).
class JobCells {
public:
    explicit JobCells(const PixelRect& r)
        : rect_(r),
          cx0_(r.x / kCellSide),
          cy0_(r.y / kCellSide),
          across_(r.width ? (r.x + r.width - 1) / kCellSide + 1 - cx0_ : 0),
          down_(r.height ? (r.y + r.height - 1) / kCellSide + 1 - cy0_ : 0) {}

    size_t count() const { return size_t(across_) * down_; }
    PixelRect operator[](size_t c) const {
        const uint32_t gx = (cx0_ + uint32_t(c % across_)) * kCellSide;
        const uint32_t gy = (cy0_ + uint32_t(c / across_)) * kCellSide;
        const uint32_t x0 = std::max(gx, rect_.x), y0 = std::max(gy, rect_.y);
        const uint32_t x1 = std::min(gx + kCellSide, rect_.x + rect_.width);
        const uint32_t y1 = std::min(gy + kCellSide, rect_.y + rect_.height);
        return {x0, y0, x1 - x0, y1 - y0};
    }

private:
    PixelRect rect_;
    uint32_t cx0_, cy0_, across_, down_;
};

// One batch: sample k[j] of the pixel at (x[j], y[j]), pixel[j] in the job's row-major
// order, j < count.
struct SampleBatch {
    // 16 lanes' worth: enough that the lanes drain (the last paths of a batch, fewer
    // than the lanes) for a small share of a batch at 4 samples a pixel and more.
    static constexpr int kMax = 16 * PathTracer::kBatch;
    std::array<uint32_t, kMax> x, y;
    std::array<uint64_t, kMax> k;
    std::array<size_t, kMax> pixel;
    int count = 0;
};

// Calls trace(batch) for each batch of the samples `job` gives `cell` (one of
// JobCells(job.rect)), in order; `batch` is the caller's, reused.
template <class Trace>
void for_each_batch(const SampleJob& job, const PixelRect& cell, SampleBatch& batch,
                    Trace&& trace) {
    const PixelRect& r = job.rect;
    batch.count = 0;
    for (uint32_t y = cell.y; y < cell.y + cell.height; ++y) {
        for (uint32_t x = cell.x; x < cell.x + cell.width; ++x) {
            const size_t i = size_t(y - r.y) * r.width + (x - r.x);
            const uint64_t first = job.first_sample[i], end = first + job.counts[i];
            for (uint64_t k = first; k < end; ++k) {
                const int j = batch.count;
                batch.x[j] = x;
                batch.y[j] = y;
                batch.k[j] = k;
                batch.pixel[j] = i;
                if (++batch.count == SampleBatch::kMax) {
                    trace(batch);
                    batch.count = 0;
                }
            }
        }
    }
    if (batch.count > 0) trace(batch);  // a batch never spans cells
    batch.count = 0;
}

}  // namespace aliquot
