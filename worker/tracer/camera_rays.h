// The start of a pixel's samples k0 .. k0 + n - 1: each one's generator, seeded from
// (seed, x, y, k) as SampleRng seeds it, and its camera ray through a uniform point of
// the pixel (a box filter, so the pixel is its area's average), made in one loop the
// compiler vectorises rather than a sample at a time.
#pragma once

#include <cstdint>

#include "camera_model.h"
#include "sampler.h"

namespace aliquot {

// n is at most PathLanes::kMax (a batch).
void camera_rays(const CameraModel& camera, uint64_t seed, uint32_t x, uint32_t y,
                 uint64_t k0, int n, Vec3* dirs, SampleRng* rngs);

}  // namespace aliquot
