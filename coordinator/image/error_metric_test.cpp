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
    // Two blocks of one pixel each (an image this small has blocks of 1): sample variance
    // of {1, -1/3} is (2/3)^2 * 2 = 8/9; over 2 blocks, sqrt(4/9).
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
    // The estimate from 64 blocks has 63 degrees of freedom: within ~3 of its 9 % sd.
    const double expected = std::sqrt(0.3 * 0.3 / 9.0 / (128.0 * 128.0)) / 0.6;
    EXPECT_NEAR(m.mean_bias_se, expected, 0.25 * expected);
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

// The standard error the commit before batch means gave: the per-pixel differences'
// standard deviation over sqrt(pixels), over the reference's mean.
double per_pixel_se(const Image& test, const Image& ref) {
    double sum = 0, sq = 0, ref_sum = 0;
    const double n = double(test.pixel_count());
    for (size_t i = 0; i < test.pixel_count(); ++i) {
        double d = 0;
        for (int c = 0; c < 3; ++c) {
            d += (test.rgb[3 * i + c] - ref.rgb[3 * i + c]) / 3.0;
            ref_sum += ref.rgb[3 * i + c];
        }
        sum += d;
        sq += d * d;
    }
    return std::sqrt((sq - sum * sum / n) / (n - 1) / n) / (ref_sum / (3 * n));
}

TEST(ErrorMetric, ErrorSharedOverEightPixelBlocksIsNotFlaggedAsBias) {
    // A denoised image's error is spread over neighbours: here one offset of zero mean
    // for each 8x8 block, all 64 pixels alike. Taken as independent pixels its standard
    // error is 8 times too small and the offsets' chance mean looks like a bias.
    Image test(128, 128), ref(128, 128);
    std::mt19937 rng(24);  // offsets' mean 1.5 of its sds off 0: plain chance
    std::vector<double> offset(16 * 16);
    for (double& o : offset)
        o = 0.1 * (2 * double(rng()) / double(std::mt19937::max()) - 1);
    for (uint32_t y = 0; y < 128; ++y)
        for (uint32_t x = 0; x < 128; ++x)
            for (int c = 0; c < 3; ++c) {
                const size_t i = (size_t(y) * 128 + x) * 3 + c;
                ref.rgb[i] = 0.5f;
                test.rgb[i] = float(0.5 + offset[(y / 8) * 16 + x / 8]);
            }
    const ErrorMetrics m = compare_images(test, ref);
    ASSERT_GT(std::abs(m.mean_bias), 3 * per_pixel_se(test, ref))
        << "this seed's offsets must fool the per-pixel error, or the test shows nothing";
    EXPECT_FALSE(bias_beyond_noise(m)) << m.mean_bias << " +- " << m.mean_bias_se;
    // The offsets' mean has sd 0.1/sqrt(3)/16 over 256 blocks, /0.5 relative.
    const double expected = 0.1 / std::sqrt(3.0) / 16.0 / 0.5;
    EXPECT_NEAR(m.mean_bias_se, expected, 0.3 * expected);
}

TEST(ErrorMetric, TheStandardErrorWeighsEdgeBlocksByTheirPixels) {
    // 18x18: blocks of 4 (16-pixel and 8-pixel blocks would be fewer than 16), 5x5 of
    // them: 16 of 16 pixels, 8 edge blocks of 8, the corner of 4. A difference of 1 in
    // the corner block's 4 pixels alone: D = 4 over N = 324 pixels, and each block's
    // residual D_k - n_k D/N weighs it by its own pixel count.
    Image test(18, 18), ref(18, 18);
    for (size_t i = 0; i < ref.rgb.size(); ++i) ref.rgb[i] = test.rgb[i] = 1.0f;
    for (uint32_t y = 16; y < 18; ++y)
        for (uint32_t x = 16; x < 18; ++x)
            for (int c = 0; c < 3; ++c) test.rgb[(size_t(y) * 18 + x) * 3 + c] = 2.0f;
    const ErrorMetrics m = compare_images(test, ref);
    const double n = 324, mean = 4 / n;
    const double spread = (4 - 4 * mean) * (4 - 4 * mean) +
                          16 * (16 * mean) * (16 * mean) + 8 * (8 * mean) * (8 * mean);
    EXPECT_DOUBLE_EQ(m.mean_bias, mean);
    EXPECT_NEAR(m.mean_bias_se, std::sqrt(25.0 / 24.0 * spread) / n, 1e-12);
}

TEST(ErrorMetric, AnImageHoldingNaNOrInfHasNoBiasNotAZeroError) {
    const Image ref = grey(2, 2, {1, 1, 1, 1});
    for (const float bad : {std::nanf(""), INFINITY, -INFINITY}) {
        for (const bool in_reference : {false, true}) {
            Image test = grey(2, 2, {1, 1, 1, 1}), reference = ref;
            (in_reference ? reference : test).rgb[4] = bad;
            const ErrorMetrics m = compare_images(test, reference);
            EXPECT_TRUE(std::isnan(m.mean_bias)) << bad << in_reference;
            EXPECT_TRUE(std::isnan(m.mean_bias_se)) << bad << in_reference;
            EXPECT_FALSE(bias_beyond_noise(m));
            EXPECT_EQ(mean_bias_text(m), "– (an image holds NaN or inf)");
        }
    }
}

TEST(ErrorMetric, TheBiasTextSaysWhyThereIsNone) {
    EXPECT_EQ(mean_bias_text(compare_images(grey(2, 2, {1, 1, 1, 1}), grey(2, 2, {}))),
              "– (the reference is black)");
    EXPECT_EQ(mean_bias_text(compare_images(grey(1, 1, {2}), grey(1, 1, {1}))),
              "+100 % (no standard error: one block)");
    const auto [dark, ref] = noisy_copy(0.98, 0.05);
    EXPECT_NE(mean_bias_text(compare_images(dark, ref)).find(", beyond 3 SE: biased"),
              std::string::npos);
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
