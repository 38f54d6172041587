// Warps: uniform random numbers in [0, 1) turned into the directions the path tracer
// samples.
#pragma once

#include <cmath>
#include <numbers>

#include "vec3.h"

namespace aliquot {

// (cos 2πu, sin 2πu) for u in [0, 1), to within 4e-7. The tracer needs one per diffuse
// bounce; the library's sincosf costs a call and twice the instructions for accuracy a
// sampled direction cannot use. Quadrant from u, then Taylor polynomials on [-π/4, π/4]
// (truncation error a^9/9! < 3.2e-7 for sin, a^10/10! < 2.5e-8 for cos).
inline void unit_circle(float u, float& c, float& s) {
    const float t = 4.0f * u;
    const int quadrant = int(t + 0.5f);  // 0..4; 4 is a full turn, the same as 0
    const float a = (t - float(quadrant)) * float(std::numbers::pi / 2);
    const float a2 = a * a;
    const float sa =
        a * (1.0f + a2 * (-1.0f / 6 + a2 * (1.0f / 120 + a2 * (-1.0f / 5040))));
    const float ca =
        1.0f + a2 * (-0.5f + a2 * (1.0f / 24 + a2 * (-1.0f / 720 + a2 * (1.0f / 40320))));
    // The quadrant turns (ca, sa) by a multiple of 90 degrees: odd quadrants swap the
    // two, quadrants 1-2 negate the cosine and 2-3 the sine. Selects, not a switch, so
    // that a loop over many paths' u vectorises (diffuse_lanes.cpp).
    const int q = quadrant & 3;
    const float x = (q & 1) ? sa : ca;
    const float y = (q & 1) ? ca : sa;
    c = ((q == 1) | (q == 2)) ? -x : x;
    s = (q & 2) ? -y : y;
}

// An orthonormal frame (s, t) around unit n (Duff et al., "Building an Orthonormal Basis,
// Revisited", JCGT 2017).
inline void build_frame(const Vec3& n, Vec3& s, Vec3& t) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    s = {1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x};
    t = {b, sign + n.y * n.y * a, -n.y};
}

// Cosine-weighted direction about unit n (Malley's method: a uniform point on the disk,
// lifted to the hemisphere); its density is cos θ / π.
inline Vec3 cosine_hemisphere(const Vec3& n, float u1, float u2) {
    const float r = std::sqrt(u1);
    float c, s;
    unit_circle(u2, c, s);
    Vec3 ts, tt;
    build_frame(n, ts, tt);
    const float z = std::sqrt(std::max(0.0f, 1.0f - u1));
    return ts * (r * c) + tt * (r * s) + n * z;
}

}  // namespace aliquot
