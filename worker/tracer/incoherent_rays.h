// Incoherent rays as a path tracer's bounces make them, for measuring raw Embree: origins
// spread through the scene's bounds, directions uniform on the sphere, drawn from the
// sample generator so every run traces the same rays (`aliquot bench`,
// bench/embree_limits).
#pragma once

#include <cstddef>
#include <vector>

#include "scene.h"

namespace aliquot {

struct RawRay {
    Vec3 origin, dir;
};

std::vector<RawRay> incoherent_rays(const Scene& scene, size_t count);

}  // namespace aliquot
