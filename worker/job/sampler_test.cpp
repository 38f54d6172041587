#include "sampler.h"

#include <gtest/gtest.h>

#include <cmath>

namespace aliquot {
namespace {

TEST(SampleRng, ReplaysTheSameSampleFromItsCoordinates) {
    SampleRng a(7, 3, 4, 100), b(7, 3, 4, 100);
    for (int i = 0; i < 64; ++i) EXPECT_EQ(a.next_u32(), b.next_u32());
}

TEST(SampleRng, DiffersWhenAnyCoordinateDiffers) {
    const uint32_t base = SampleRng(7, 3, 4, 100).next_u32();
    EXPECT_NE(base, SampleRng(8, 3, 4, 100).next_u32());
    EXPECT_NE(base, SampleRng(7, 4, 4, 100).next_u32());
    EXPECT_NE(base, SampleRng(7, 3, 5, 100).next_u32());
    EXPECT_NE(base, SampleRng(7, 3, 4, 101).next_u32());
    // x and y must not be interchangeable.
    EXPECT_NE(SampleRng(7, 3, 4, 0).next_u32(), SampleRng(7, 4, 3, 0).next_u32());
}

TEST(SampleRng, FloatsAreUniformInUnitInterval) {
    // Across many samples' first draws (the ones that place a sample in its pixel), the
    // mean and variance must be those of U[0,1): 1/2 and 1/12, within 5 standard errors.
    const int n = 200000;
    double sum = 0, sum2 = 0;
    for (int k = 0; k < n; ++k) {
        const float u = SampleRng(1, 0, 0, uint64_t(k)).next_float();
        ASSERT_GE(u, 0.0f);
        ASSERT_LT(u, 1.0f);
        sum += u;
        sum2 += double(u) * u;
    }
    const double mean = sum / n, var = sum2 / n - mean * mean;
    EXPECT_NEAR(mean, 0.5, 5 * std::sqrt(1.0 / 12 / n));
    EXPECT_NEAR(var, 1.0 / 12, 5 * std::sqrt(1.0 / 180 / n));
}

}  // namespace
}  // namespace aliquot
