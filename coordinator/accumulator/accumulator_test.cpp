#include "accumulator.h"

#include "aov_channels.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace aliquot {
namespace {

SampleJobResult one_pixel(uint32_t x, uint32_t y, double even, double odd, uint64_t n,
                          double sum_sq) {
    SampleJobResult r;
    r.rect = {x, y, 1, 1};
    r.pixels.resize(1);
    r.pixels[0].even[0] = r.pixels[0].even[1] = r.pixels[0].even[2] = even;
    r.pixels[0].odd[0] = r.pixels[0].odd[1] = r.pixels[0].odd[2] = odd;
    r.pixels[0].samples = n;
    r.pixels[0].sum_sq_luminance = sum_sq;
    r.pixels[0].rays = 3 * n;
    return r;
}

TEST(Accumulator, MeanIsTheSumOverAllSamples) {
    Accumulator acc(2, 1);
    acc.merge(one_pixel(1, 0, 3.0, 1.0, 4, 0));
    double rgb[3];
    acc.mean(1, rgb);
    EXPECT_DOUBLE_EQ(rgb[0], 1.0);
    acc.mean(0, rgb);
    EXPECT_DOUBLE_EQ(rgb[0], 0.0);  // no samples: black, not NaN
    EXPECT_EQ(acc.total_samples(), 4u);
    EXPECT_EQ(acc.total_rays(), 12u);
}

// The merge derives each pixel's half difference and luminance variance two pixels at a
// time: every pixel of a row of odd width (the last one alone), of 0, 1 and more samples,
// holds exactly what the definitions give, bit for bit.
TEST(Accumulator, DerivedValuesAreTheirDefinitionsForEveryPixelOfARow) {
    Accumulator acc(9, 2);
    SampleJobResult r;
    r.rect = {1, 0, 7, 2};
    r.pixels.resize(r.rect.size());
    for (size_t i = 0; i < r.pixels.size(); ++i) {
        PixelSums& p = r.pixels[i];
        p.samples = i % 5;  // 0, 1, 2, 3, 4, 0, 1, ...
        for (int c = 0; c < 3; ++c) {
            p.even[c] = p.samples ? 0.1 * double(i + 1) * (c + 1) : 0.0;
            p.odd[c] = p.samples > 1 ? 0.37 * double(i % 3) + 0.01 * c : 0.0;
        }
        p.sum_sq_luminance = p.samples ? 0.7 * double(i) + 0.3 : 0.0;
        if (i == 4)  // halves of -0.0 and +0.0: the difference is +0.0, not -0.0
            for (int c = 0; c < 3; ++c) p.even[c] = -0.0, p.odd[c] = 0.0;
    }
    acc.merge(r);
    acc.merge(r);  // the second merge derives from the sums so far
    for (size_t i = 0; i < acc.pixel_count(); ++i) {
        const PixelSums& p = acc.at(i);
        double even[3], odd[3];
        acc.half_means(i, even, odd);
        const double difference =
            p.samples < 2 ? -1.0
                          : (std::abs(even[0] - odd[0]) + std::abs(even[1] - odd[1]) +
                             std::abs(even[2] - odd[2])) /
                                3.0;
        double variance = 0;
        if (p.samples >= 2) {
            const double n = double(p.samples);
            const double sum = luminance(p.even[0] + p.odd[0], p.even[1] + p.odd[1],
                                         p.even[2] + p.odd[2]);
            variance = std::max(0.0, (p.sum_sq_luminance - sum * sum / n) / (n - 1.0));
        }
        const double got_difference = acc.half_difference(i);
        const double got_variance = acc.luminance_variance(i);
        EXPECT_EQ(std::memcmp(&got_difference, &difference, sizeof difference), 0) << i;
        EXPECT_EQ(std::memcmp(&got_variance, &variance, sizeof variance), 0) << i;
        EXPECT_EQ(acc.samples(i), p.samples);
        EXPECT_EQ(acc.rays(i), p.rays);
    }
}

TEST(Accumulator, HalvesCountEvenAndOddSamplesSeparately) {
    Accumulator acc(1, 1);
    acc.merge(one_pixel(0, 0, 6.0, 2.0, 5, 0));  // 3 even samples (0, 2, 4), 2 odd
    double even[3], odd[3];
    acc.half_means(0, even, odd);
    EXPECT_DOUBLE_EQ(even[0], 2.0);
    EXPECT_DOUBLE_EQ(odd[0], 1.0);
}

TEST(Accumulator, LuminanceVarianceIsTheUnbiasedSampleVariance) {
    // Samples of luminance 1 and 3 (grey, so luminance equals the channel value).
    Accumulator acc(1, 1);
    acc.merge(one_pixel(0, 0, 1.0, 3.0, 2, 1.0 + 9.0));
    EXPECT_NEAR(acc.luminance_variance(0), 2.0, 1e-5);
    // Kept as results merge: two more samples (luminance 2 and 2) give the variance of
    // {1, 3, 2, 2}, 2/3; one sample alone has none.
    acc.merge(one_pixel(0, 0, 2.0, 2.0, 2, 4.0 + 4.0));
    EXPECT_NEAR(acc.luminance_variance(0), 2.0 / 3.0, 1e-12);
    Accumulator lone(2, 1);
    lone.merge(one_pixel(1, 0, 5.0, 0.0, 1, 25.0));
    EXPECT_EQ(lone.luminance_variance(0), 0.0);
    EXPECT_EQ(lone.luminance_variance(1), 0.0);
}

TEST(Accumulator, AovsGiveSppAndVarianceOfTheMean) {
    Accumulator acc(1, 1);
    acc.merge(one_pixel(0, 0, 1.0, 3.0, 2, 10.0));
    const Image img = acc.image(true);
    ASSERT_EQ(img.extra.size(), 2u);
    EXPECT_EQ(img.extra[0].name, kSampleCountChannel);
    EXPECT_FLOAT_EQ(img.extra[0].values[0], 2.0f);
    EXPECT_EQ(img.extra[1].name, kVarianceChannel);
    EXPECT_NEAR(img.extra[1].values[0], 1.0f, 1e-5);  // sample variance 2 over 2 samples
    EXPECT_TRUE(acc.image(false).extra.empty());
}

TEST(Accumulator, RefusesResultsOutsideTheImageWithoutTouchingIt) {
    Accumulator acc(2, 2);
    EXPECT_THROW(acc.merge(one_pixel(2, 0, 1, 1, 2, 1)), MergeError);
    SampleJobResult wrong = one_pixel(0, 0, 1, 1, 2, 1);
    wrong.rect.width = 2;  // claims two pixels, carries one
    EXPECT_THROW(acc.merge(wrong), MergeError);
    EXPECT_EQ(acc.total_samples(), 0u);
}

// Issue 12, reproduction 3: each incoming value was finite, the merged one was not, and
// the image held inf while the render still ended done.
TEST(Accumulator, RefusesAResultThatWouldMakeAMergedSumNonFinite) {
    Accumulator acc(2, 1);
    EXPECT_THROW(acc.merge(one_pixel(0, 0, 1.7e308, 0.0, 2, 0)), MergeError);
    acc.merge(one_pixel(0, 0, 6e29, 0.0, 2, 0));
    EXPECT_THROW(acc.merge(one_pixel(0, 0, 1.7e308, 0.0, 2, 0)), MergeError);
    double rgb[3];
    acc.mean(0, rgb);
    EXPECT_DOUBLE_EQ(rgb[0], 3e29);
    EXPECT_EQ(acc.total_samples(), 2u);
}

// Issue 30, item 8: sums of 9e99 stayed under the old cap of 1e100 on the sums, but
// their mean over one sample is no float32: the EXR held +inf pixels and the render
// ended done. The bound is on the mean, so every float made from the sums is finite.
TEST(Accumulator, RefusesAResultWhoseMeanWouldOverflowAFloat) {
    Accumulator acc(2, 1);
    EXPECT_THROW(acc.merge(one_pixel(0, 0, 9e99, 0.0, 1, 0)), MergeError);
    EXPECT_THROW(acc.merge(one_pixel(0, 0, 0.0, 0.0, 2, 1e40)), MergeError);  // variance
    EXPECT_THROW(acc.merge(one_pixel(1, 0, 1.0, 0.0, 0, 0)), MergeError);  // no samples
    EXPECT_EQ(acc.total_samples(), 0u);
    EXPECT_EQ(acc.at(0), PixelSums{});
    // Right at the bound, every float of the image is finite.
    acc.merge(one_pixel(0, 0, 1e30, 1e30, 2, 2e30));
    acc.merge(one_pixel(1, 0, 1e30, 0.0, 1, 1e30));
    const Image img = acc.image(true);
    for (float v : img.rgb) EXPECT_TRUE(std::isfinite(v)) << v;
    for (const Image::Channel& c : img.extra)
        for (float v : c.values) EXPECT_TRUE(std::isfinite(v)) << c.name << " " << v;
}

TEST(Accumulator, ARefusedResultMergesNoneOfItsPixels) {
    Accumulator acc(2, 1);
    SampleJobResult r;
    r.rect = {0, 0, 2, 1};
    r.pixels.resize(2);
    r.pixels[0].even[0] = 1.0;
    r.pixels[0].samples = r.pixels[1].samples = 1;
    r.pixels[1].sum_sq_luminance = 1e300;  // its square would not be finite
    EXPECT_THROW(acc.merge(r), MergeError);
    EXPECT_EQ(acc.total_samples(), 0u);
    EXPECT_EQ(acc.at(0).samples, 0u);
    EXPECT_EQ(acc.at(0).even[0], 0.0);
}

// Results within a quarter of the bound merge after a look at their own sums alone
// (accumulator.h, roomy_): a bad pixel anywhere in a long result, past the first blocks
// looked at, still refuses all of it; and after sums at the bound, results are checked
// against the buffers again and still merge when they fit.
TEST(Accumulator, AResultIsRefusedWholeForABadPixelAnywhereAfterRoomyMerges) {
    Accumulator acc(1000, 1);
    SampleJobResult r;
    r.rect = {0, 0, 1000, 1};
    r.pixels.resize(1000);
    for (PixelSums& p : r.pixels) p.samples = 2, p.even[0] = 0.5;
    acc.merge(r);
    for (const size_t bad : {size_t(999), size_t(300)}) {
        SampleJobResult broken = r;
        broken.pixels[bad].odd[2] = std::nan("");
        EXPECT_THROW(acc.merge(broken), MergeError) << bad;
        broken.pixels[bad].odd[2] = 1.7e308;
        EXPECT_THROW(acc.merge(broken), MergeError) << bad;
    }
    EXPECT_EQ(acc.total_samples(), 2000u);
    EXPECT_EQ(acc.at(999).odd[2], 0.0);
    SampleJobResult at_bound = r;
    at_bound.pixels[5].even[1] = 2e30;  // 1e30 a sample: no longer roomy, still merged
    acc.merge(at_bound);
    acc.merge(r);
    EXPECT_EQ(acc.total_samples(), 6000u);
    EXPECT_EQ(acc.at(5).even[1], 2e30);
    SampleJobResult over = r;
    over.pixels[5].even[1] = 7e30;  // 9e30 over 8 samples: past 1e30 a sample
    EXPECT_THROW(acc.merge(over), MergeError);
}

// Issue 33: the render session's check of a result against its job joined the merge's
// one pass. With the job's counts, a pixel unlike its job anywhere refuses the result
// whole, with the session's reason as before; the pass totals what it adds.
TEST(Accumulator, CheckWithCountsRefusesAResultUnlikeItsJobWholeAndTotalsTheRest) {
    Accumulator acc(300, 1);
    SampleJobResult r;
    r.rect = {0, 0, 300, 1};
    r.pixels.resize(300);
    std::vector<uint32_t> counts(300, 2);
    counts[7] = 0;  // a pixel the job gave no samples
    for (size_t i = 0; i < r.pixels.size(); ++i)
        if (counts[i])
            r.pixels[i].samples = 2, r.pixels[i].even[1] = 0.5, r.pixels[i].rays = 5;
    const auto refused = [&](SampleJobResult bad) {
        try {
            acc.check(bad, counts.data());
        } catch (const MergeError& e) {
            return std::string(e.what());
        }
        return std::string("taken");
    };
    SampleJobResult bad = r;
    bad.pixels[250].samples = 3;
    bad.pixels[250].even[0] = 9;  // roomy: only the count is wrong
    EXPECT_EQ(refused(bad), "pixel 250 has 3 samples, job asked for 2");
    bad = r;
    bad.pixels[7].rays = 1;
    EXPECT_EQ(refused(bad), "pixel 7 has no samples but non-zero sums");
    bad = r;
    bad.pixels[299].nonfinite = 3;
    EXPECT_EQ(refused(bad), "more non-finite samples than samples");
    bad = r;
    bad.pixels[100].odd[2] = INFINITY;
    EXPECT_EQ(refused(bad), "non-finite sum at pixel 100");
    bad = r;
    bad.pixels[100].sum_sq_luminance = -1;
    EXPECT_EQ(refused(bad), "bad sum of squares at pixel 100");
    EXPECT_EQ(acc.total_samples(), 0u);
    EXPECT_EQ(acc.at(100).samples, 0u);
    const ResultTotals totals = acc.check(r, counts.data());
    EXPECT_EQ(totals.samples, 598u);
    EXPECT_EQ(totals.rays, 5u * 299);
    acc.add(r, totals);
    EXPECT_EQ(acc.total_samples(), 598u);
    EXPECT_EQ(acc.total_rays(), 5u * 299);
    EXPECT_EQ(acc.at(1).even[1], 0.5);
    // check_as_asked, for a result held before it merges, says the same.
    bad = r;
    bad.pixels[250].samples = 3;
    EXPECT_THROW(check_as_asked(bad, counts.data()), MergeError);
    EXPECT_EQ(check_as_asked(r, counts.data()).samples, 598u);
}

// A render's buffers come zeroed from the kernel, half differences at -1, however large.
TEST(Accumulator, ANewAccumulatorIsZeroWhateverItsSize) {
    for (const uint32_t side : {3u, 1100u}) {  // calloc'd, and mapped
        Accumulator acc(side, side);
        acc.touch_pages();
        for (const size_t i :
             {size_t(0), size_t(side) * side / 2, size_t(side) * side - 1}) {
            EXPECT_EQ(acc.at(i), PixelSums{});
            EXPECT_EQ(acc.samples(i), 0u);
            EXPECT_EQ(acc.rays(i), 0u);
            EXPECT_EQ(acc.half_difference(i), -1.0);
            EXPECT_EQ(acc.luminance_variance(i), 0.0);
        }
        acc.merge(one_pixel(side - 1, side - 1, 1, 1, 2, 1));
        Accumulator moved = std::move(acc);
        EXPECT_EQ(moved.total_samples(), 2u);
        EXPECT_EQ(moved.at(size_t(side) * side - 1).samples, 2u);
    }
}

TEST(Accumulator, CopyFromMakesAnEqualCopyOverAnyPreviousContents) {
    // Several bands of pixels, so the copy runs on the pool's threads.
    Accumulator source(400, 400), copy(3, 2);
    for (uint32_t y = 0; y < 400; y += 7)
        for (uint32_t x = 0; x < 400; x += 3)
            source.merge(one_pixel(x, y, x * 0.5, y * 0.25, 2 + x % 5, 1.0 + y));
    copy.merge(one_pixel(1, 1, 9, 9, 9, 9));
    copy.copy_from(source);
    ASSERT_EQ(copy.width(), 400u);
    ASSERT_EQ(copy.height(), 400u);
    EXPECT_EQ(copy.total_samples(), source.total_samples());
    EXPECT_EQ(copy.total_rays(), source.total_rays());
    for (size_t i = 0; i < source.pixel_count(); ++i) {
        ASSERT_EQ(std::memcmp(&copy.at(i), &source.at(i), sizeof(PixelSums)), 0) << i;
        ASSERT_EQ(copy.samples(i), source.samples(i)) << i;
        ASSERT_EQ(copy.rays(i), source.rays(i)) << i;
        ASSERT_EQ(copy.half_difference(i), source.half_difference(i)) << i;
        ASSERT_EQ(copy.luminance_variance(i), source.luminance_variance(i)) << i;
    }
}

TEST(Accumulator, SampleAndRayCountsFollowEveryMerge) {
    Accumulator acc(3, 1);
    acc.merge(one_pixel(1, 0, 1.0, 1.0, 4, 0));
    acc.merge(one_pixel(1, 0, 1.0, 1.0, 3, 0));
    acc.merge(one_pixel(2, 0, 1.0, 1.0, 1, 0));
    EXPECT_EQ(acc.samples(0), 0u);
    EXPECT_EQ(acc.samples(1), 7u);
    EXPECT_EQ(acc.samples(2), 1u);
    EXPECT_EQ(acc.rays(0), 0u);
    EXPECT_EQ(acc.rays(1), 21u);  // one_pixel traces 3 rays a sample
    EXPECT_EQ(acc.rays(2), 3u);
    for (size_t i = 0; i < 3; ++i) {
        EXPECT_EQ(acc.samples(i), acc.at(i).samples);
        EXPECT_EQ(acc.rays(i), acc.at(i).rays);
    }
}

TEST(Accumulator, HalfDifferenceIsTheHalvesMeanGapOverRgbFromTwoSamples) {
    Accumulator acc(2, 1);
    EXPECT_EQ(acc.half_difference(0), -1.0);  // no samples
    acc.merge(one_pixel(0, 0, 6.0, 0.0, 1, 0));
    EXPECT_EQ(acc.half_difference(0), -1.0);  // one sample: no odd half yet
    // Then 5 samples: 3 even summing to 6 (mean 2) and 2 odd summing to 2 (mean 1)...
    acc.merge(one_pixel(0, 0, 0.0, 2.0, 4, 0));
    EXPECT_DOUBLE_EQ(acc.half_difference(0), 1.0);
    // ... and what a fresh computation from the merged sums gives, to the bit.
    SampleJobResult r = one_pixel(1, 0, 1.0, 0.25, 3, 0);
    r.pixels[0].even[1] = 0.7;
    r.pixels[0].odd[2] = 0.3;
    acc.merge(r);
    double even[3], odd[3];
    acc.half_means(1, even, odd);
    EXPECT_EQ(acc.half_difference(1),
              (std::abs(even[0] - odd[0]) + std::abs(even[1] - odd[1]) +
               std::abs(even[2] - odd[2])) /
                  3.0);
}

}  // namespace
}  // namespace aliquot
