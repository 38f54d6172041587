#include "warp.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sampler.h"

namespace aliquot {
namespace {

TEST(Warp, UnitCircleMatchesCosAndSinEverywhere) {
    double worst = 0;
    for (int i = 0; i < 1 << 16; ++i) {
        const float u = float(i) / float(1 << 16);
        float c, s;
        unit_circle(u, c, s);
        const double phi = 2 * std::numbers::pi * double(u);
        worst =
            std::max({worst, std::abs(c - std::cos(phi)), std::abs(s - std::sin(phi))});
    }
    EXPECT_LT(worst, 4e-7);
    float c, s;
    unit_circle(std::nextafter(1.0f, 0.0f), c, s);  // the largest u a SampleRng returns
    EXPECT_NEAR(c, 1.0f, 1e-6f);
    EXPECT_NEAR(s, 0.0f, 1e-6f);
}

TEST(Warp, CosineHemisphereIsUnitAboveTheNormalWithCosineMean) {
    // E[cos θ] = 2/3 for the density cos θ / π.
    const Vec3 normals[] = {{0, 0, 1}, {0, 0, -1}, normalize(Vec3(0.3f, -0.8f, 0.1f))};
    for (const Vec3& n : normals) {
        double sum = 0;
        const int count = 200000;
        for (int k = 0; k < count; ++k) {
            SampleRng rng(7, 1, 2, uint64_t(k));
            const float u1 = rng.next_float(), u2 = rng.next_float();
            const Vec3 d = cosine_hemisphere(n, u1, u2);
            ASSERT_NEAR(length(d), 1.0f, 2e-6f);
            ASSERT_GE(dot(d, n), -1e-6f);
            sum += dot(d, n);
        }
        EXPECT_NEAR(sum / count, 2.0 / 3.0, 5 * std::sqrt((0.5 - 4.0 / 9.0) / count));
    }
}

}  // namespace
}  // namespace aliquot
