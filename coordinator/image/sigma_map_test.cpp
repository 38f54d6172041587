#include "sigma_map.h"

#include <gtest/gtest.h>

namespace aliquot {
namespace {

TEST(SigmaMap, IsTheSquareRootOfTheMeansVarianceTimesSpp) {
    Image image(2, 1);
    image.extra = {{"spp", {4, 100}}, {"variance", {0.25f, 0.01f}}};
    const std::vector<float> sigma = per_sample_sigma(image);
    EXPECT_FLOAT_EQ(sigma[0], 1.0f);
    EXPECT_FLOAT_EQ(sigma[1], 1.0f);
}

TEST(SigmaMap, AnImageWithoutItsAovsIsRefused) {
    EXPECT_THROW(per_sample_sigma(Image(2, 2)), std::invalid_argument);
    Image bad(1, 1);
    bad.extra = {{"spp", {4}}, {"variance", {-1}}};
    EXPECT_THROW(per_sample_sigma(bad), std::invalid_argument);
}

}  // namespace
}  // namespace aliquot
