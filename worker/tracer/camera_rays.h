// The start of a batch of pixel samples: each one's generator, seeded from (seed, x, y,
// k) as SampleRng seeds it, and its camera ray through a uniform point of its pixel (a
// box filter, so the pixel is its area's average), made in one loop the compiler
// vectorises rather than a sample at a time. A batch's samples may come from many pixels
// (a cell's, trace_job.cpp), so each lane names its own pixel.
#pragma once

#include <cstdint>

#include "camera_model.h"
#include "path_lanes.h"
#include "sampler.h"

namespace aliquot {

// Samples k[j] of the pixels at (x[j], y[j]), j = 0 .. n - 1; n is at most
// PathLanes::kMax.
void camera_rays(const CameraModel& camera, uint64_t seed, const uint32_t* x,
                 const uint32_t* y, const uint64_t* k, int n, Vec3* dirs,
                 SampleRng* rngs);

}  // namespace aliquot
