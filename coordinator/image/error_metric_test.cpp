// Error metrics on small images whose values are worked out by hand.
#include "error_metric.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace aliquot {
namespace {

// An image whose every channel of pixel i equals values[i]; no values: black.
Image grey(uint32_t w, uint32_t h, const std::vector<float>& values) {
    Image image(w, h);
    if (values.empty()) return image;
    for (size_t i = 0; i < image.pixel_count(); ++i)
        for (int c = 0; c < 3; ++c) image.rgb[3 * i + c] = values[i];
    return image;
}

TEST(ErrorMetric, IdenticalImagesHaveZeroError) {
    const Image a = grey(3, 2, {1, 2, 3, 4, 5, 6});
    const ErrorMetrics m = compare_images(a, a);
    EXPECT_EQ(m.mean_abs, 0);
    EXPECT_EQ(m.rmse, 0);
    EXPECT_EQ(m.relative_mse, 0);
    EXPECT_EQ(m.max_bucket, 0);
    EXPECT_EQ(m.p99_bucket, 0);
}

TEST(ErrorMetric, MatchesHandComputedValues) {
    Image test(2, 1), ref(2, 1);
    test.rgb = {1, 2, 3, 0, 0, 0};
    ref.rgb = {0, 0, 0, 0, 0, 1};
    const ErrorMetrics m = compare_images(test, ref);
    // Pixel errors averaged over RGB: (1+2+3)/3 = 2 and 1/3.
    EXPECT_DOUBLE_EQ(m.mean_abs, (2.0 + 1.0 / 3.0) / 2.0);
    EXPECT_DOUBLE_EQ(m.rmse, std::sqrt((1.0 + 4.0 + 9.0 + 1.0) / 6.0));
    EXPECT_DOUBLE_EQ(m.relative_mse,
                     (1.0 / 0.01 + 4.0 / 0.01 + 9.0 / 0.01 + 1.0 / 1.01) / 6.0);
    // One bucket holds the whole image.
    EXPECT_DOUBLE_EQ(m.max_bucket, m.mean_abs);
    EXPECT_DOUBLE_EQ(m.p99_bucket, m.mean_abs);
}

TEST(ErrorMetric, RelativeMseDividesByTheReference) {
    const Image dark = grey(1, 1, {0}), bright = grey(1, 1, {1});
    EXPECT_DOUBLE_EQ(compare_images(bright, dark).relative_mse, 1.0 / 0.01);
    EXPECT_DOUBLE_EQ(compare_images(dark, bright).relative_mse, 1.0 / 1.01);
}

TEST(ErrorMetric, MaxBucketFindsTheOneBadBucket) {
    // 4x4 in 2x2 buckets; only the top-right bucket differs, by 2 in one pixel.
    std::vector<float> values(16, 0.0f);
    values[3] = 2;
    const ErrorMetrics m = compare_images(grey(4, 4, values), grey(4, 4, {}), 2);
    EXPECT_DOUBLE_EQ(m.mean_abs, 2.0 / 16.0);
    EXPECT_DOUBLE_EQ(m.max_bucket, 2.0 / 4.0);
}

TEST(ErrorMetric, EdgeBucketsAreSmallerAndAveragedOverTheirOwnPixels) {
    // 3x3 in 2x2 buckets: the corner bucket is the single pixel (2,2).
    std::vector<float> values(9, 0.0f);
    values[8] = 1;
    const ErrorMetrics m = compare_images(grey(3, 3, values), grey(3, 3, {}), 2);
    EXPECT_DOUBLE_EQ(m.mean_abs, 1.0 / 9.0);
    EXPECT_DOUBLE_EQ(m.max_bucket, 1.0);
}

TEST(ErrorMetric, P99IsNearestRankOverBuckets) {
    // 200 one-pixel buckets with errors 1..200: nearest rank ceil(0.99*200) = 198.
    std::vector<float> values;
    for (int i = 1; i <= 200; ++i) values.push_back(float(i));
    const ErrorMetrics m = compare_images(grey(200, 1, values), grey(200, 1, {}), 1);
    EXPECT_DOUBLE_EQ(m.max_bucket, 200.0);
    EXPECT_DOUBLE_EQ(m.p99_bucket, 198.0);
}

TEST(ErrorMetric, P99OfFewBucketsIsTheMaximum) {
    // With 10 buckets, ceil(0.99*10) = 10: the largest.
    std::vector<float> values;
    for (int i = 1; i <= 10; ++i) values.push_back(float(i));
    const ErrorMetrics m = compare_images(grey(10, 1, values), grey(10, 1, {}), 1);
    EXPECT_DOUBLE_EQ(m.p99_bucket, 10.0);
}

TEST(ErrorMetric, WholeImageMetricsDoNotDependOnBucketSize) {
    Image test(37, 23), ref(37, 23);
    for (size_t i = 0; i < test.rgb.size(); ++i) {
        test.rgb[i] = 0.1f * float(i % 13);
        ref.rgb[i] = 0.07f * float(i % 11);
    }
    const ErrorMetrics a = compare_images(test, ref, 1),
                       b = compare_images(test, ref, 16);
    EXPECT_EQ(a.mean_abs, b.mean_abs);
    EXPECT_EQ(a.rmse, b.rmse);
    EXPECT_EQ(a.relative_mse, b.relative_mse);
    EXPECT_EQ(a.mean_bias, b.mean_bias);
    EXPECT_EQ(a.mean_bias_se, b.mean_bias_se);
}

// A reference with structure (0.2..1.0, mean 0.6) and a test image that is it times
// `scale` plus zero-mean noise of half-width `noise` in every channel. The noise comes
// from mt19937's raw output, which the standard fixes, so the image is the same on every
// platform.
std::pair<Image, Image> noisy_copy(double scale, double noise) {
    Image test(128, 128), ref(128, 128);
    std::mt19937 rng(7);
    for (size_t i = 0; i < ref.pixel_count(); ++i) {
        const float base = 0.2f + 0.8f * float((i * 37) % 101) / 100.0f;
        for (int c = 0; c < 3; ++c) {
            const double u = double(rng()) / double(std::mt19937::max());  // [0, 1]
            ref.rgb[3 * i + c] = base;
            test.rgb[3 * i + c] = float(base * scale + noise * (2 * u - 1));
        }
    }
    return {test, ref};
}

TEST(ErrorMetric, MeanBiasIsTheRelativeDifferenceOfTheImageMeans) {
    // Reference mean 1; pixel differences +1 and -1/3 (over RGB): mean 1/3.
    Image test(2, 1), ref(2, 1);
    test.rgb = {2, 2, 2, 1, 1, 0};
    ref.rgb = {1, 1, 1, 1, 1, 1};
    const ErrorMetrics m = compare_images(test, ref);
    EXPECT_DOUBLE_EQ(m.mean_bias, 1.0 / 3.0);
    // Sample variance of {1, -1/3} is (2/3)^2 * 2 = 8/9; over 2 pixels, sqrt(4/9).
    EXPECT_DOUBLE_EQ(m.mean_bias_se, 2.0 / 3.0);
    EXPECT_FALSE(bias_beyond_noise(m));
}

TEST(ErrorMetric, AnImageTwoPercentTooDarkIsFlagged) {
    const auto [test, ref] = noisy_copy(0.98, 0.05);
    const ErrorMetrics m = compare_images(test, ref);
    EXPECT_NEAR(m.mean_bias, -0.02, 0.001);
    EXPECT_LT(m.mean_bias_se, 0.001);
    EXPECT_TRUE(bias_beyond_noise(m));
}

TEST(ErrorMetric, ZeroMeanNoiseIsNotFlaggedAndItsStandardErrorIsTheNoises) {
    const auto [test, ref] = noisy_copy(1.0, 0.3);
    const ErrorMetrics m = compare_images(test, ref);
    EXPECT_FALSE(bias_beyond_noise(m)) << m.mean_bias << " +- " << m.mean_bias_se;
    // A uniform of half-width a has variance a^2/3; a pixel's mean of 3 channels, a^2/9.
    const double expected = std::sqrt(0.3 * 0.3 / 9.0 / (128.0 * 128.0)) / 0.6;
    EXPECT_NEAR(m.mean_bias_se, expected, 0.05 * expected);
    EXPECT_GT(m.mean_abs, 0.1);  // far more noise than bias, yet no flag
}

TEST(ErrorMetric, IdenticalImagesHaveNoBias) {
    const Image a = grey(3, 2, {1, 2, 3, 4, 5, 6});
    const ErrorMetrics m = compare_images(a, a);
    EXPECT_EQ(m.mean_bias, 0);
    EXPECT_EQ(m.mean_bias_se, 0);
    EXPECT_FALSE(bias_beyond_noise(m));
}

TEST(ErrorMetric, ABlackReferenceHasNoRelativeBias) {
    const ErrorMetrics m = compare_images(grey(2, 2, {1, 1, 1, 1}), grey(2, 2, {}));
    EXPECT_TRUE(std::isnan(m.mean_bias));
    EXPECT_TRUE(std::isnan(m.mean_bias_se));
    EXPECT_FALSE(bias_beyond_noise(m));
    EXPECT_DOUBLE_EQ(m.mean_abs, 1.0);  // the other metrics stay defined
}

TEST(ErrorMetric, DifferentResolutionsThrowNamingBoth) {
    try {
        compare_images(Image(64, 64), Image(128, 128));
        FAIL() << "expected ImageMismatch";
    } catch (const ImageMismatch& e) {
        EXPECT_STREQ(e.what(), "resolution differs: 64x64 vs 128x128");
    }
}

TEST(ErrorMetric, NonPositiveBucketSizeIsRejected) {
    EXPECT_THROW(compare_images(Image(4, 4), Image(4, 4), 0), std::invalid_argument);
}

}  // namespace
}  // namespace aliquot
