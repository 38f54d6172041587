// Accumulator: a render's per-pixel sums in double precision, merged from sample jobs.
// Everything a strategy or an output needs is derived from it.
#pragma once

#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "image.h"
#include "page_buffer.h"
#include "sample_job.h"

namespace aliquot {

class MergeError : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

// What a checked result adds (Accumulator::check), counted in the one pass that checks
// it: nobody walks a result again to total it.
struct ResultTotals {
    uint64_t samples = 0, rays = 0, nonfinite = 0;
};

// Throws MergeError unless `result` is what a job of `counts` (one a pixel, as many as
// the result's pixels) asked for: Accumulator::check's test of them, reading no buffer,
// for a result held before it can merge. What it adds.
ResultTotals check_as_asked(const SampleJobResult& result, const uint32_t* counts);

class Accumulator {
public:
    // Memory a pixel takes: its sums, its sample and ray counts, its half difference and
    // its luminance variance.
    static constexpr size_t kBytesPerPixel =
        sizeof(PixelSums) + 2 * sizeof(uint64_t) + 2 * sizeof(double);

    Accumulator() = default;
    // Zeroed and mapped by the kernel (page_buffer.h), not written again.
    Accumulator(uint32_t width, uint32_t height);
    Accumulator(Accumulator&& other) noexcept;
    Accumulator& operator=(Accumulator&& other) noexcept;
    Accumulator(const Accumulator& other) { copy_from(other); }
    Accumulator& operator=(const Accumulator& other) {
        copy_from(other);
        return *this;
    }

    // Faults in every page now, should any be out: a copy prepared off the locks for a
    // round end to fill takes no fault.
    void touch_pages();

    // Becomes a copy of `other`, reusing this one's memory when the sizes match (a
    // checkpoint's copy each round), the bytes copied in bands on the pool's threads.
    void copy_from(const Accumulator& other);

    uint32_t width() const { return width_; }
    uint32_t height() const { return height_; }
    size_t pixel_count() const { return pixels_.size(); }

    // Adds a job's sums: check(), then add(). Throws MergeError, touching nothing, when
    // the result does not fit the image (rectangle outside it, wrong pixel count) or
    // would make a merged sum non-finite or larger than 1e30 times the pixel's samples:
    // the buffers stay finite, and so does every float of the image made from them,
    // whatever a worker sends.
    void merge(const SampleJobResult& result);
    // Throws MergeError unless merge() would take `result`; with `counts` (the job's,
    // one a pixel), also unless each pixel has its count of samples, no more non-finite
    // samples than samples, finite sums and a sum of squares not below 0, and all zero
    // where it has no samples (a worker may not put light where nothing was traced).
    // One pass over the result (and the buffers under it only when its sums are large),
    // which totals it too. Reads only the rectangle's pixels.
    ResultTotals check(const SampleJobResult& result, const uint32_t* counts = nullptr);
    // Adds a result check() took. Writes only the rectangle's pixels and the totals
    // (atomically): adds of disjoint rectangles may run at once, from any threads, beside
    // readers of other pixels.
    void add(const SampleJobResult& result, const ResultTotals& totals);

    const PixelSums& at(size_t i) const { return pixels_[i]; }
    // Read from an array of counts kept beside the sums: passes that need only the counts
    // (cutting a round into jobs, the strategies' plans) stream 8 bytes a pixel instead
    // of the sums' 80 (16 MB instead of 160 MB at 1920x1080).
    uint64_t samples(size_t i) const { return samples_[i]; }
    // Likewise the rays: optimal-time's costs (rays per sample) at a round's end read 16
    // bytes a pixel, not the sums (~20 ms of each of its round ends at 1920x1080).
    uint64_t rays(size_t i) const { return rays_[i]; }

    // Mean RGB of pixel i over all its samples (0 with no samples).
    void mean(size_t i, double rgb[3]) const;
    // Mean RGB over even-index / odd-index samples only: two independent half estimates.
    void half_means(size_t i, double even[3], double odd[3]) const;
    // Sample variance of one sample's luminance at pixel i (0 below two samples). Kept
    // as results merge, as the half difference is: optimal's round end reads 8 bytes a
    // pixel for its sigma instead of streaming the 80-byte sums (~25 ms of each of its
    // round ends at 1920x1080), and the work moves to the merges, which overlap the
    // workers' tracing.
    double luminance_variance(size_t i) const { return luminance_variance_[i]; }
    // Mean over RGB of |even half mean - odd half mean| at pixel i, or -1 below two
    // samples: what the error estimate and Dammertz's seed norm are made of. Kept as
    // results merge, while the merged pixels are in cache, so a round's end reads 8
    // bytes a pixel for it instead of streaming the sums once more.
    double half_difference(size_t i) const { return half_difference_[i]; }

    uint64_t total_samples() const {
        return total_samples_.load(std::memory_order_relaxed);
    }
    uint64_t total_rays() const { return total_rays_.load(std::memory_order_relaxed); }
    uint64_t total_nonfinite() const {
        return total_nonfinite_.load(std::memory_order_relaxed);
    }

    // The image; with `aovs`, the layers of aov_channels.h: "sampleCount.Y" (samples per
    // pixel) and "variance.Y" (estimated variance of the pixel's mean luminance, sample
    // variance / samples).
    Image image(bool aovs = false) const;

private:
    void check_finite_after(const SampleJobResult& result) const;

    uint32_t width_ = 0, height_ = 0;
    PageBuffer<PixelSums> pixels_;
    // Derived from pixels_ and kept in step with it by merge(): see samples(),
    // rays(), half_difference() and luminance_variance().
    PageBuffer<uint64_t> samples_, rays_;
    PageBuffer<double> half_difference_, luminance_variance_;
    // Atomic: adds of disjoint rectangles run at once (add()).
    std::atomic<uint64_t> total_samples_ = 0, total_rays_ = 0, total_nonfinite_ = 0;
    // Whether every sum merged so far came in a result within a quarter of the bound
    // merge() keeps (so every buffer is within three quarters of it): then a result
    // within a quarter is merged without reading the buffers to check it. Checks of
    // disjoint rectangles running at once may clear it; each reads the pixels of its
    // own rectangle only, whose last add happened before (the render's lock orders
    // them), so what it read of the flag covers them.
    std::atomic<bool> roomy_ = true;
};

}  // namespace aliquot
