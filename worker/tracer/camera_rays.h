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

// Which sample each lane of a batch is: sample k[j] of pixel (x[j], y[j]).
struct SampleLanes {
    uint32_t x[PathLanes::kMax], y[PathLanes::kMax];
    uint64_t k[PathLanes::kMax];
};

// Lanes 0 .. n - 1 of `samples`; n is at most PathLanes::kMax (a batch).
void camera_rays(const CameraModel& camera, uint64_t seed, const SampleLanes& samples,
                 int n, Vec3* dirs, SampleRng* rngs);

}  // namespace aliquot
