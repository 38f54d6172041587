// Ray against an analytic sphere, in our own code beside Embree's BVH of meshes: a scene
// has a handful of spheres (cornell-caustics has two), and testing each directly costs a
// few nanoseconds a ray, where Embree's point-sphere primitive made every query of that
// scene ~1.7x slower than the box's (docs/PERFORMANCE.md, "both scenes, idle machine").
#pragma once

#include <cmath>
#include <limits>

#include "vec3.h"

namespace aliquot {

// The nearest t in (0, tmax) with |origin + t*dir - center| = radius, or +inf if none.
// `dir` need not be unit length. The discriminant is formed as r^2 - |f|^2, with f the
// offset of the centre from the ray's closest point, and the second root from the
// first's product (Haines et al., "Precision Improvements for Ray/Sphere Intersection",
// Ray Tracing Gems, 2019, ch. 7): the textbook b^2 - ac cancels catastrophically for a
// small sphere far away, and a path leaving a sphere's surface needs the far root exact.
// Written with selects, not early returns, so that a loop of it over many rays
// vectorises (sphere_lanes.cpp); a ray that misses computes NaNs the selects discard.
inline float sphere_hit_t(const Vec3& origin, const Vec3& dir, const Vec3& center,
                          float radius, float tmax) {
    constexpr float kMiss = std::numeric_limits<float>::infinity();
    const Vec3 oc = origin - center;
    const float a = dot(dir, dir);
    const float b = dot(oc, dir);  // half of the quadratic's b
    const float c = dot(oc, oc) - radius * radius;
    const Vec3 f = oc - dir * (b / a);
    const float d = radius * radius - dot(f, f);  // discriminant / a
    const float q = -b - std::copysign(std::sqrt(a * d), b);
    // q == 0: the origin on the surface, tangent: no crossing.
    const bool crosses = (d >= 0.0f) & (q != 0.0f);
    const float t0 = c / q, t1 = q / a;
    const float near = t0 > t1 ? t1 : t0, far = t0 > t1 ? t0 : t1;
    const bool near_in = crosses & (near > 0.0f) & (near < tmax);
    const bool far_in = crosses & (far > 0.0f) & (far < tmax);
    return near_in ? near : (far_in ? far : kMiss);
}

}  // namespace aliquot
