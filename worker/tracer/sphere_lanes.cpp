#include "sphere_lanes.h"

#include "sphere_hit.h"

namespace aliquot {

// Without fused multiply-adds (the tracer's build) every clone gives the same bits.
__attribute__((target_clones("avx512f", "avx2", "default"))) void nearest_spheres(
    const std::vector<Sphere>& spheres, RayLanes& r, int count) {
    for (int i = 0; i < count; ++i) r.sphere[i] = -1;
    for (size_t s = 0; s < spheres.size(); ++s) {
        const Vec3 center = spheres[s].center;
        const float radius = spheres[s].radius;
        for (int i = 0; i < count; ++i) {
            const float t =
                sphere_hit_t(Vec3(r.ox[i], r.oy[i], r.oz[i]),
                             Vec3(r.dx[i], r.dy[i], r.dz[i]), center, radius, r.t[i]);
            const bool nearer = t < r.t[i];
            r.t[i] = nearer ? t : r.t[i];
            r.sphere[i] = nearer ? int32_t(s) : r.sphere[i];
        }
    }
}

}  // namespace aliquot
