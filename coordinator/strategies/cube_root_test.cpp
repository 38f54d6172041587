#include "cube_root.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace aliquot {
namespace {

// Within 2e-15 of std::cbrt over the whole range of normal doubles, including the
// exponents' residues mod 3 where the guess is worst.
TEST(CubeRoot, IsWithin2e15OfStdCbrtOverTheNormalDoubles) {
    std::mt19937_64 random(7);
    std::uniform_real_distribution<double> exponent(-1021, 1023);
    std::uniform_real_distribution<double> mantissa(1, 2);
    double worst = 0;
    for (int k = 0; k < 200000; ++k) {
        const double x = std::ldexp(mantissa(random), int(exponent(random)));
        worst = std::max(worst, std::abs(cube_root(x) / std::cbrt(x) - 1));
    }
    for (double x : {1.0, 2.0, 4.0, 8.0, 0.125, 27.0, std::numeric_limits<double>::min(),
                     std::numeric_limits<double>::max()})
        worst = std::max(worst, std::abs(cube_root(x) / std::cbrt(x) - 1));
    EXPECT_LT(worst, 2e-15);
}

TEST(CubeRoot, WhereTheStepsDoNotHoldItIsStdCbrt) {
    const double inf = std::numeric_limits<double>::infinity();
    const double subnormal = std::numeric_limits<double>::denorm_min() * 12345;
    EXPECT_FALSE(cube_root_steps_hold(0.0));
    EXPECT_FALSE(cube_root_steps_hold(subnormal));
    EXPECT_FALSE(cube_root_steps_hold(inf));
    EXPECT_FALSE(cube_root_steps_hold(std::nan("")));
    EXPECT_FALSE(cube_root_steps_hold(-8.0));
    EXPECT_EQ(cube_root(0.0), 0.0);
    EXPECT_EQ(cube_root(subnormal), std::cbrt(subnormal));
    EXPECT_EQ(cube_root(inf), inf);
    EXPECT_TRUE(std::isnan(cube_root(std::nan(""))));
    EXPECT_EQ(cube_root(-8.0), -2.0);
}

}  // namespace
}  // namespace aliquot
