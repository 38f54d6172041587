// Shading arithmetic shared by the one-path shading (path_tracer.cpp) and the batched
// diffuse shading (diffuse_lanes.cpp): both must do the same float operations in the same
// order, so that a path's bytes do not depend on which of the two shaded it.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include "vec3.h"

namespace aliquot {

inline constexpr float kInvPi = float(1.0 / std::numbers::pi);

// Rays leave a surface from a point pushed off it along the geometric normal, to the side
// they travel to; scaled by the point's magnitude so float spacing never swallows it.
inline float offset_scale(const Vec3& p) {
    return 1e-4f *
           (1.0f + std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z))));
}
// (Adding ng times a negated scale is subtracting ng times the scale, to the bit; one
// select of a float, not of a Vec3, keeps a loop over lanes free of branches.)
inline Vec3 offset_origin(const Vec3& p, const Vec3& ng, float scale, const Vec3& dir) {
    return p + ng * (dot(dir, ng) > 0 ? scale : -scale);
}

inline float power_heuristic(float a, float b) {
    const float a2 = a * a;
    return a2 > 0 ? a2 / (a2 + b * b) : 0.0f;
}

// a where c holds, else b: a select a component at a time, which a loop over lanes
// vectorises (a select of whole Vec3s compiles to a branch).
inline Vec3 select(bool c, const Vec3& a, const Vec3& b) {
    return {c ? a.x : b.x, c ? a.y : b.y, c ? a.z : b.z};
}

// Russian roulette's survival probability, Mitsuba's: the throughput's largest component
// times the squared product of IORs crossed, at most 0.95.
inline float survival(const Vec3& beta, float eta) {
    return std::min(max_component(beta) * eta * eta, 0.95f);
}

}  // namespace aliquot
