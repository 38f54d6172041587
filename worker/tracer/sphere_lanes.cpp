#include "sphere_lanes.h"

#include "simd_clones.h"
#include "sphere_hit.h"

namespace aliquot {

ALIQUOT_SIMD_CLONES void nearest_spheres(const std::vector<Sphere>& spheres, RayLanes& r,
                                         int count) {
    // All kMax lanes, those past the count repeating ray 0: a loop of a fixed count runs
    // as whole SIMD vectors, where a partial packet's count would leave a remainder to
    // go one ray at a time.
    for (int i = count; i < RayLanes::kMax; ++i) {
        r.ox[i] = r.ox[0], r.oy[i] = r.oy[0], r.oz[i] = r.oz[0];
        r.dx[i] = r.dx[0], r.dy[i] = r.dy[0], r.dz[i] = r.dz[0];
        r.t[i] = r.t[0];
    }
    for (int i = 0; i < RayLanes::kMax; ++i) r.sphere[i] = -1;
    for (size_t s = 0; s < spheres.size(); ++s) {
        const Vec3 center = spheres[s].center;
        const float radius = spheres[s].radius;
        for (int i = 0; i < RayLanes::kMax; ++i) {
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
