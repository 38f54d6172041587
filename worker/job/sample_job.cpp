#include "sample_job.h"

namespace aliquot {

uint64_t SampleJobResult::total_samples() const {
    uint64_t n = 0;
    for (const PixelSums& p : pixels) n += p.samples;
    return n;
}
uint64_t SampleJobResult::total_rays() const {
    uint64_t n = 0;
    for (const PixelSums& p : pixels) n += p.rays;
    return n;
}
uint64_t SampleJobResult::total_nonfinite() const {
    uint64_t n = 0;
    for (const PixelSums& p : pixels) n += p.nonfinite;
    return n;
}

void add_sample(PixelSums& sums, uint64_t index, const Vec3& radiance, uint32_t rays) {
    ++sums.samples;
    sums.rays += rays;
    if (!is_finite(radiance)) {
        ++sums.nonfinite;
        return;
    }
    double* half = (index % 2 == 0) ? sums.even : sums.odd;
    half[0] += radiance.x;
    half[1] += radiance.y;
    half[2] += radiance.z;
    const double lum = luminance(radiance);
    sums.sum_sq_luminance += lum * lum;
}

void add_first_hit(FirstHitSums& sums, const Vec3& albedo, const Vec3& normal) {
    sums.albedo[0] += albedo.x;
    sums.albedo[1] += albedo.y;
    sums.albedo[2] += albedo.z;
    sums.normal[0] += normal.x;
    sums.normal[1] += normal.y;
    sums.normal[2] += normal.z;
}

}  // namespace aliquot
