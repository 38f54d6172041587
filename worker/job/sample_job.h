// SampleJob: the unit of work. A pixel rectangle, how many samples each pixel gets, and
// the index of each pixel's first sample; and SampleJobResult, the per-pixel sums it
// returns. Plain data shared by the worker that traces a job and the coordinator that
// merges it.
#pragma once

#include <cstdint>
#include <vector>

#include "sums_array.h"
#include "vec3.h"

namespace aliquot {

struct PixelRect {
    uint32_t x = 0, y = 0, width = 0, height = 0;
    size_t size() const { return size_t(width) * height; }
    bool operator==(const PixelRect&) const = default;
};

// The tracer batches a round's samples by cells of kCellSide x kCellSide pixels, on a
// grid from the image's origin clipped at its edges (worker/tracer/trace_job.cpp), so
// that its batches are full when pixels get few samples. Which samples share a batch
// changes a sample's last bits (Embree's packets), so rounds are cut into jobs on cell
// boundaries (round_cutter.h): then how a round is cut changes no bit.
inline constexpr uint32_t kCellSide = 8;

struct SampleJob {
    PixelRect rect;
    std::vector<uint32_t> counts;  // per pixel of rect, row-major
    std::vector<uint64_t>
        first_sample;  // per pixel: index of its first sample in this job
    // Also sum each sample's first hit (FirstHitSums): only renders that will be
    // denoised ask, so no one else's samples or results grow.
    bool aux = false;
};

// What a denoiser (OIDN) reads beside the colour, summed over a pixel's samples like the
// colour so the mean is sum / samples: the first hit's albedo (reflectance of a diffuse
// or mirror surface, 1 for a dielectric: OIDN's first-hit convention) and its normal in
// world space, facing the ray. A sample whose camera ray leaves the scene adds 0 to both.
struct FirstHitSums {
    double albedo[3] = {0, 0, 0};
    double normal[3] = {0, 0, 0};

    bool operator==(const FirstHitSums&) const = default;
};

// What a job returns for one pixel. Sums over samples k = first .. first+count-1 in order
// of k, so a pixel's sums depend on nothing but the job and the seed.
struct PixelSums {
    double even[3] = {0, 0, 0};  // RGB sum over even sample indices
    double odd[3] = {0, 0, 0};   // RGB sum over odd sample indices
    double sum_sq_luminance = 0;
    uint64_t samples = 0;
    uint64_t rays = 0;
    // Samples whose radiance was NaN or infinite: counted in `samples` as zero radiance,
    // so a broken sample costs its share of the budget but never poisons a sum.
    uint64_t nonfinite = 0;

    bool operator==(const PixelSums&) const = default;
};

// Its sums are owned, or read where a message's bytes hold them for as long as the
// message lives (SumsArray): such a result is passed on by reference, since a copy or a
// move of it copies its sums.
struct SampleJobResult {
    PixelRect rect;
    SumsArray<PixelSums> pixels;  // per pixel of rect, row-major
    double wall_seconds = 0;      // statistics only: nothing may decide on it
    // Per pixel of rect for a job with `aux`; empty for any other.
    SumsArray<FirstHitSums> first_hits;

    uint64_t total_samples() const;
    uint64_t total_rays() const;
    uint64_t total_nonfinite() const;
};

struct RenderGeometry {
    uint32_t width = 0, height = 0;  // the whole image
    uint64_t seed = 0;
};

// One sample's contribution before it is summed: exposed for tests of the NaN guard.
void add_sample(PixelSums& sums, uint64_t index, const Vec3& radiance, uint32_t rays);
// One sample's first hit, added in sample order as add_sample adds its radiance.
void add_first_hit(FirstHitSums& sums, const Vec3& albedo, const Vec3& normal);

}  // namespace aliquot
