#include "sphere_hit.h"

#include <gtest/gtest.h>

#include <cmath>

namespace aliquot {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

TEST(SphereHit, FromOutsideTheNearRootFromInsideTheFar) {
    const Vec3 c(0, 0, 0);
    EXPECT_FLOAT_EQ(sphere_hit_t({0, 0, -5}, {0, 0, 1}, c, 1, kInf), 4.0f);
    EXPECT_FLOAT_EQ(sphere_hit_t({0, 0, 0.5f}, {0, 0, 1}, c, 1, kInf), 0.5f);
    // Not unit length: t is in units of dir.
    EXPECT_FLOAT_EQ(sphere_hit_t({0, 0, -5}, {0, 0, 2}, c, 1, kInf), 2.0f);
}

TEST(SphereHit, MissesBehindBesideAndBeyondTmax) {
    const Vec3 c(0, 0, 0);
    EXPECT_EQ(sphere_hit_t({0, 0, -5}, {0, 0, -1}, c, 1, kInf), kInf);     // behind
    EXPECT_EQ(sphere_hit_t({0, 1.01f, -5}, {0, 0, 1}, c, 1, kInf), kInf);  // beside
    EXPECT_EQ(sphere_hit_t({0, 0, -5}, {0, 0, 1}, c, 1, 3.9f), kInf);      // beyond tmax
    EXPECT_EQ(sphere_hit_t({0, 0, -5}, {0, 0, 1}, c, 1, 4.0f), kInf);      // open at tmax
}

// A path leaving a sphere starts a hair off its surface (offset_origin): outside and
// heading away it must not hit the sphere again; inside it must find the far side.
TEST(SphereHit, APathLeavingTheSurfaceDoesNotHitItAgain) {
    const Vec3 c(-0.4f, -0.6f, -0.2f);
    const float r = 0.4f, offset = 1e-4f;
    for (int i = 0; i < 1000; ++i) {
        const float a = 0.0123f * float(i), b = 0.0371f * float(i);
        const Vec3 n(std::cos(a) * std::sin(b), std::sin(a) * std::sin(b), std::cos(b));
        const Vec3 out = c + n * (r + offset), in = c + n * (r - offset);
        // Away from the sphere, within 80 degrees of the normal.
        const Vec3 away = normalize(n + Vec3(0.3f, -0.2f, 0.1f) * 0.5f);
        if (dot(away, n) <= 0.2f) continue;
        EXPECT_EQ(sphere_hit_t(out, away, c, r, kInf), kInf);
        // Into the sphere: the chord's length 2 r cos(theta), from just inside.
        EXPECT_NEAR(sphere_hit_t(in, -away, c, r, kInf), 2 * r * dot(away, n), 1e-3f)
            << i;
    }
}

// The textbook b^2 - ac loses every digit for a small sphere far away; the form used
// keeps the hit on the surface.
TEST(SphereHit, ASmallSphereFarAwayIsHitOnItsSurface) {
    const Vec3 c(0, 0, 100);  // float still resolves 1e-5 here; at 1e4 it would not
    const float r = 0.01f;
    const Vec3 o(0, 0.005f, 0);
    const float t = sphere_hit_t(o, {0, 0, 1}, c, r, kInf);
    ASSERT_LT(t, kInf);
    const Vec3 p = o + Vec3(0, 0, 1) * t;
    EXPECT_NEAR(length(p - c), r, 2e-3f * r);
}

}  // namespace
}  // namespace aliquot
