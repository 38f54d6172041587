// Ray against an analytic sphere, in our own code beside Embree's BVH of meshes: a scene
// has a handful of spheres (cornell-caustics has two), and testing each directly costs a
// few nanoseconds a ray, where Embree's point-sphere primitive made every query of that
// scene ~1.7x slower than the box's (docs/PERFORMANCE.md, "both scenes, idle machine").
#pragma once

#include <cmath>
#include <limits>
#include <utility>

#include "vec3.h"

namespace aliquot {

// The nearest t in (0, tmax) with |origin + t*dir - center| = radius, or +inf if none.
// `dir` need not be unit length. The discriminant is formed as r^2 - |f|^2, with f the
// offset of the centre from the ray's closest point, and the second root from the
// first's product (Haines et al., "Precision Improvements for Ray/Sphere Intersection",
// Ray Tracing Gems, 2019, ch. 7): the textbook b^2 - ac cancels catastrophically for a
// small sphere far away, and a path leaving a sphere's surface needs the far root exact.
inline float sphere_hit_t(const Vec3& origin, const Vec3& dir, const Vec3& center,
                          float radius, float tmax) {
    constexpr float kMiss = std::numeric_limits<float>::infinity();
    const Vec3 oc = origin - center;
    const float a = dot(dir, dir);
    const float b = dot(oc, dir);  // half of the quadratic's b
    const float c = dot(oc, oc) - radius * radius;
    const Vec3 f = oc - dir * (b / a);
    const float d = radius * radius - dot(f, f);  // discriminant / a
    if (!(d >= 0.0f)) return kMiss;
    const float q = -b - std::copysign(std::sqrt(a * d), b);
    if (q == 0.0f) return kMiss;  // the origin on the surface, tangent: no crossing
    float t0 = c / q, t1 = q / a;
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > 0.0f && t0 < tmax) return t0;
    if (t1 > 0.0f && t1 < tmax) return t1;
    return kMiss;
}

}  // namespace aliquot
