#include "dammertz_strategy.h"

#include <gtest/gtest.h>

#include "synthetic_source.h"

namespace aliquot {
namespace {

StrategyParams dammertz(double max_variance, uint32_t per_iteration = 16) {
    StrategyParams p;
    p.method = "dammertz";
    p.max_variance = max_variance;
    p.samples_per_iteration = per_iteration;
    return p;
}

// Every pixel lies in exactly one bucket.
void expect_partition(const std::vector<Bucket>& buckets, uint32_t w, uint32_t h) {
    std::vector<int> covered(size_t(w) * h, 0);
    for (const Bucket& b : buckets) {
        ASSERT_GT(b.rect.size(), 0u);
        ASSERT_LE(b.rect.x + b.rect.width, w);
        ASSERT_LE(b.rect.y + b.rect.height, h);
        for (uint32_t y = b.rect.y; y < b.rect.y + b.rect.height; ++y)
            for (uint32_t x = b.rect.x; x < b.rect.x + b.rect.width; ++x)
                ++covered[size_t(y) * w + x];
    }
    for (int c : covered) ASSERT_EQ(c, 1);
}

// Noise that varies over the image: a smooth ramp plus a noisy spot.
SyntheticImage varied_image(uint32_t w, uint32_t h) {
    SyntheticImage image(w, h, 7);
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x) {
            const double ramp = double(x) / w;
            const int dx = int(x) - 30, dy = int(y) - 10;
            const bool spot = dx * dx + dy * dy < 40;
            image.at(x, y) = {0.5, 0.02 + 0.3 * ramp * ramp + (spot ? 0.6 : 0.0)};
        }
    return image;
}

TEST(Dammertz, BucketsPartitionTheImageAfterEveryRound) {
    const SyntheticImage image = varied_image(48, 40);
    StrategyParams p = dammertz(0.01, 8);
    p.max_spp = 512;
    DammertzStrategy strategy(p, 48, 40);
    Accumulator merged(48, 40);
    size_t most_leaves = 0;
    const SyntheticRun run = run_synthetic(
        strategy, image, merged, 1000, [&](const Round&, const Accumulator&) {
            expect_partition(strategy.buckets(), 48, 40);
            most_leaves = std::max(most_leaves, strategy.leaves().size());
        });
    EXPECT_TRUE(run.finished);
    expect_partition(strategy.buckets(), 48, 40);
    EXPECT_GT(most_leaves, 8u);  // the tree did split
}

TEST(Dammertz, SplitsPerpendicularToLongerAxis) {
    // E after 16 samples is about 0.08: above V = 0.01, below 64 V, so the root splits.
    for (const auto& [w, h] : {std::pair{64u, 16u}, std::pair{16u, 64u}}) {
        const SyntheticImage image(w, h, 1, {0.5, 0.2});
        DammertzStrategy strategy(dammertz(0.01), w, h);
        Accumulator merged(w, h);
        run_synthetic(strategy, image, merged, 1);
        strategy.next_round(merged);
        ASSERT_EQ(strategy.leaves().size(), 2u);
        const PixelRect a = strategy.leaves()[0].rect, b = strategy.leaves()[1].rect;
        if (w > h) {
            EXPECT_EQ(a.height, h);  // a vertical cut across the long x axis
            EXPECT_EQ(b.height, h);
            EXPECT_EQ(a.width + b.width, w);
        } else {
            EXPECT_EQ(a.width, w);
            EXPECT_EQ(b.width, w);
            EXPECT_EQ(a.height + b.height, h);
        }
    }
}

TEST(Dammertz, SplitCutsWhereTheErrorIsHalved) {
    // All error in the left 16 of 64 columns: half of it lies left of column 8.
    const PixelRect rect{0, 0, 64, 16};
    std::vector<double> errors(rect.size(), 0.0);
    for (uint32_t y = 0; y < 16; ++y)
        for (uint32_t x = 0; x < 16; ++x) errors[y * 64 + x] = 1.0;
    const auto halves = DammertzStrategy::split(rect, errors, 4);
    ASSERT_TRUE(halves);
    EXPECT_EQ(halves->first, (PixelRect{0, 0, 8, 16}));
    EXPECT_EQ(halves->second, (PixelRect{8, 0, 56, 16}));
}

TEST(Dammertz, SplitsAtTheErrorHalvingPositionOfARenderedImage) {
    SyntheticImage image(64, 16, 2, {0.5, 0.0});
    for (uint32_t y = 0; y < 16; ++y)
        for (uint32_t x = 0; x < 16; ++x) image.at(x, y).sigma = 1.0;
    DammertzStrategy strategy(dammertz(0.01), 64, 16);
    Accumulator merged(64, 16);
    run_synthetic(strategy, image, merged, 1);
    strategy.next_round(merged);
    ASSERT_EQ(strategy.leaves().size(), 2u);
    EXPECT_NEAR(double(strategy.leaves()[0].rect.width), 8.0, 2.0);
}

TEST(Dammertz, SplitNeverLeavesASideBelowMinBucketSize) {
    const PixelRect rect{3, 5, 9, 2};
    std::vector<double> errors(rect.size(), 0.0);
    errors[0] = 1.0;  // all error in the first column would cut at 1
    const auto halves = DammertzStrategy::split(rect, errors, 4);
    ASSERT_TRUE(halves);
    EXPECT_EQ(halves->first.width, 4u);
    EXPECT_FALSE(DammertzStrategy::split({0, 0, 7, 7}, std::vector<double>(49, 1.0), 4));
}

TEST(Dammertz, StopsWhereErrorIsAtMostV) {
    const SyntheticImage image(48, 32, 4, {0.5, 0.2});
    StrategyParams p = dammertz(0.02);
    DammertzStrategy strategy(p, 48, 32);
    Accumulator merged(48, 32);
    const SyntheticRun run = run_synthetic(
        strategy, image, merged, 1000, [&](const Round& round, const Accumulator&) {
            // A bucket judged converged gets no more samples.
            for (const Bucket& b : strategy.buckets()) {
                if (!b.converged) continue;
                ASSERT_EQ(round.spp[size_t(b.rect.y) * 48 + b.rect.x], 0u);
            }
        });
    ASSERT_TRUE(run.finished);
    EXPECT_EQ(strategy.outcome()["stopped_by"], "converged");
    EXPECT_EQ(strategy.outcome()["converged_fraction"], 1.0);
    for (const auto& leaf : strategy.leaves()) {
        EXPECT_EQ(leaf.state, DammertzStrategy::State::converged);
        EXPECT_LE(leaf.error, 0.02);
    }
}

TEST(Dammertz, ABucketBelowVAfterItsFirstRoundIsDoneAtOnce) {
    const SyntheticImage image(16, 16, 4, {0.5, 0.001});
    DammertzStrategy strategy(dammertz(0.01), 16, 16);
    Accumulator merged(16, 16);
    const SyntheticRun run = run_synthetic(strategy, image, merged);
    EXPECT_TRUE(run.finished);
    EXPECT_EQ(run.rounds, 1u);
    EXPECT_EQ(merged.total_samples(), 16u * 256);
}

TEST(Dammertz, ABucketTooSmallToSplitKeepsSampling) {
    const SyntheticImage image(6, 6, 5, {0.5, 0.2});  // E ~ 0.08: in the split range
    DammertzStrategy strategy(dammertz(0.01), 6, 6);
    Accumulator merged(6, 6);
    run_synthetic(strategy, image, merged, 1);
    const auto round = strategy.next_round(merged);
    ASSERT_TRUE(round);
    EXPECT_EQ(strategy.leaves().size(), 1u);
    EXPECT_EQ(round->spp[0], 16u);
}

TEST(Dammertz, MaxSppStopsAnUnreachableVAndOutcomeSaysWhatDidNotConverge) {
    const SyntheticImage image = varied_image(40, 24);
    StrategyParams p = dammertz(1e-9);
    p.max_spp = 64;
    DammertzStrategy strategy(p, 40, 24);
    Accumulator merged(40, 24);
    const SyntheticRun run = run_synthetic(strategy, image, merged, 100);
    ASSERT_TRUE(run.finished);
    EXPECT_EQ(run.rounds, 4u);
    for (size_t i = 0; i < merged.pixel_count(); ++i) ASSERT_EQ(merged.samples(i), 64u);
    const nlohmann::json outcome = strategy.outcome();
    EXPECT_EQ(outcome["stopped_by"], "max_spp");
    EXPECT_EQ(outcome["converged_fraction"], 0.0);
    EXPECT_EQ(outcome["unconverged_pixels"], 40 * 24);
    EXPECT_EQ(outcome["unconverged_buckets"], strategy.leaves().size());
}

TEST(Dammertz, MaxSamplesStopsItWithoutExceedingIt) {
    const SyntheticImage image = varied_image(40, 24);
    StrategyParams p = dammertz(1e-9);
    p.max_samples = 960 * 40 + 7;  // room for 16 + 16 + 8 samples per pixel
    DammertzStrategy strategy(p, 40, 24);
    Accumulator merged(40, 24);
    const SyntheticRun run = run_synthetic(strategy, image, merged, 100);
    ASSERT_TRUE(run.finished);
    EXPECT_EQ(run.rounds, 3u);
    EXPECT_EQ(merged.total_samples(), 960u * 40);
    EXPECT_EQ(strategy.outcome()["stopped_by"], "max_samples");
}

TEST(Dammertz, ABudgetActsAsMaxSamples) {
    StrategyParams p = dammertz(0.01);
    p.budget = 5000;
    EXPECT_EQ(DammertzStrategy(p, 10, 10).max_samples(), 5000u);
    EXPECT_EQ(DammertzStrategy(dammertz(0.01), 10, 10).max_samples(), 409600u);
    EXPECT_EQ(DammertzStrategy(dammertz(0.01), 10, 10).max_spp(), 65536u);
}

// A 4x4 image whose every pixel has two samples: 1 (even index) and 3 (odd index), grey.
Accumulator two_sample_image() {
    Accumulator merged(4, 4);
    SampleJobResult result;
    result.rect = {0, 0, 4, 4};
    result.pixels.resize(16);
    for (PixelSums& p : result.pixels) {
        for (int c = 0; c < 3; ++c) {
            p.even[c] = 1;
            p.odd[c] = 3;
        }
        p.samples = 2;
    }
    merged.merge(result);
    return merged;
}

TEST(Dammertz, SeedNormIsTheMeanAbsoluteDifferenceOfTheHalves) {
    DammertzStrategy strategy(dammertz(0.01), 4, 4);
    const auto errors = strategy.pixel_errors(two_sample_image(), {0, 0, 2, 2});
    EXPECT_DOUBLE_EQ(strategy.bucket_error(errors), 2.0);
}

TEST(Dammertz, PaperNormScalesBySquareRootOfTheBucketsShareOfTheImage) {
    StrategyParams p = dammertz(0.01);
    p.error_norm = "paper";
    DammertzStrategy strategy(p, 4, 4);
    const Accumulator merged = two_sample_image();
    // I = 2, A = 1 per channel: sum |I - A| / sqrt(sum I) = 3 / sqrt(6).
    const double pixel = 3 / std::sqrt(6.0);
    EXPECT_DOUBLE_EQ(strategy.bucket_error(strategy.pixel_errors(merged, {0, 0, 4, 4})),
                     pixel);
    EXPECT_DOUBLE_EQ(strategy.bucket_error(strategy.pixel_errors(merged, {0, 0, 2, 2})),
                     pixel * 0.5);
}

TEST(Dammertz, PaperNormOfABlackPixelIsZero) {
    StrategyParams p = dammertz(0.01);
    p.error_norm = "paper";
    DammertzStrategy strategy(p, 4, 4);
    Accumulator merged(4, 4);
    EXPECT_EQ(strategy.pixel_errors(merged, {0, 0, 4, 4}), std::vector<double>(16, 0.0));
}

TEST(Dammertz, RestoredStateMakesTheSameDecisions) {
    const SyntheticImage image = varied_image(40, 24);
    StrategyParams p = dammertz(0.01, 8);
    p.max_spp = 256;
    DammertzStrategy whole(p, 40, 24);
    Accumulator a(40, 24);
    std::vector<std::vector<uint32_t>> rounds;
    run_synthetic(whole, image, a, 1000,
                  [&](const Round& r, const Accumulator&) { rounds.push_back(r.spp); });

    DammertzStrategy first(p, 40, 24);
    Accumulator b(40, 24);
    run_synthetic(first, image, b, 5);
    DammertzStrategy resumed(p, 40, 24);
    resumed.restore_state(nlohmann::json::parse(first.save_state().dump()));
    size_t r = 5;
    run_synthetic(resumed, image, b, 1000, [&](const Round& round, const Accumulator&) {
        ASSERT_LT(r, rounds.size());
        EXPECT_EQ(round.spp, rounds[r++]);
    });
    EXPECT_EQ(r, rounds.size());
    EXPECT_EQ(resumed.outcome(), whole.outcome());
}

}  // namespace
}  // namespace aliquot
