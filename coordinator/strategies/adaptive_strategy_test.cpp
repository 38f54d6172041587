#include "adaptive_strategy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include "synthetic_source.h"

namespace aliquot {
namespace {

StrategyParams adaptive(uint64_t budget, double max_variance = 10, double alpha = 1) {
    StrategyParams p;
    p.method = "adaptive";
    p.budget = budget;
    p.initial_spp = 16;
    p.max_variance = max_variance;
    p.alpha = alpha;
    return p;
}

// Four 16x16 buckets side by side whose noise doubles from one to the next.
SyntheticImage graded_image() {
    SyntheticImage image(64, 16, 11);
    for (uint32_t y = 0; y < 16; ++y)
        for (uint32_t x = 0; x < 64; ++x)
            image.at(x, y) = {0.5, 0.05 * double(1 << (x / 16))};
    return image;
}

// Samples each bucket got beyond the initial pass, and the bucket variances.
struct Spread {
    std::vector<double> extra, variance;
};

Spread run_graded(const StrategyParams& p) {
    const SyntheticImage image = graded_image();
    AdaptiveStrategy strategy(p, 64, 16);
    Accumulator merged(64, 16);
    EXPECT_TRUE(run_synthetic(strategy, image, merged).finished);
    EXPECT_EQ(merged.total_samples(), p.budget);
    Spread s;
    for (const Bucket& b : strategy.buckets()) {
        double extra = 0;
        for (uint32_t x = b.rect.x; x < b.rect.x + b.rect.width; ++x)
            for (uint32_t y = 0; y < 16; ++y)
                extra += double(merged.samples(y * 64 + x)) - 16;
        s.extra.push_back(extra);
        s.variance.push_back(b.error);
    }
    return s;
}

double share(const Spread& s, size_t b) {
    double total = 0;
    for (double e : s.extra) total += e;
    return s.extra[b] / total;
}

TEST(Adaptive, SpendsExactlyItsBudget) {
    SyntheticImage image(37, 29, 5, {0.5, 0.1});  // edge buckets are partial
    for (uint32_t x = 0; x < 10; ++x) image.at(x, 3).sigma = 2.0;
    for (uint64_t budget : {37u * 29 * 16, 37u * 29 * 20 + 123, 37u * 29 * 50 + 1}) {
        AdaptiveStrategy strategy(adaptive(budget), 37, 29);
        Accumulator merged(37, 29);
        ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
        EXPECT_EQ(merged.total_samples(), budget);
        EXPECT_EQ(strategy.outcome()["unspent"], 0);
    }
}

TEST(Adaptive, GivesEachBucketMinOfVOverMaxVarianceToTheAlphaOfTheRemainder) {
    for (double alpha : {0.5, 1.0, 3.0}) {
        const Spread s = run_graded(adaptive(1024 * 100, 10, alpha));
        for (size_t b = 0; b < 4; ++b) {
            const double expected = std::pow(s.variance[b] / s.variance[3], alpha);
            // Whole samples: a bucket is off by less than one sample per pixel.
            EXPECT_NEAR(s.extra[b], s.extra[3] * expected, 256) << "alpha " << alpha;
        }
    }
}

TEST(Adaptive, HigherAlphaConcentratesSamplesOnTheNoisiestBuckets) {
    // min(v / V, 1)^alpha: raising alpha shrinks every weight below 1, the more the
    // smaller v is. (The seed's prose says the opposite; its numbers agree with the
    // formula.)
    const Spread low = run_graded(adaptive(1024 * 100, 10, 0.5));
    const Spread mid = run_graded(adaptive(1024 * 100, 10, 1));
    const Spread high = run_graded(adaptive(1024 * 100, 10, 4));
    EXPECT_LT(share(low, 3), share(mid, 3));
    EXPECT_LT(share(mid, 3), share(high, 3));
    EXPECT_GT(share(low, 0), share(mid, 0));
    EXPECT_GT(share(mid, 0), share(high, 0));
}

TEST(Adaptive, AlphaZeroSpendsTheRemainderUniformly) {
    const Spread s = run_graded(adaptive(1024 * 100, 10, 0));
    for (double e : s.extra) EXPECT_NEAR(e, 256 * 84, 256);
}

TEST(Adaptive, TinyMaxVarianceSaturatesEveryNoisyBucket) {
    const Spread s = run_graded(adaptive(1024 * 100, 1e-12, 1));
    for (double e : s.extra) EXPECT_NEAR(e, 256 * 84, 256);
}

TEST(Adaptive, HugeMaxVarianceKeepsTheProportionsOfV) {
    // v / 1e12 is tiny, and to the 50th power it underflows a double; the weights are
    // relative, so they must come out as (v_b / v_max)^alpha all the same.
    const Spread normal = run_graded(adaptive(1024 * 100, 10, 2));
    const Spread huge = run_graded(adaptive(1024 * 100, 1e12, 2));
    for (size_t b = 0; b < 4; ++b) EXPECT_NEAR(huge.extra[b], normal.extra[b], 256);
    const Spread steep = run_graded(adaptive(1024 * 100, 1e12, 50));
    EXPECT_GT(share(steep, 3), 0.99);
}

TEST(Adaptive, AFlatImageGetsTheRestUniformly) {
    const SyntheticImage image(40, 20, 1, {0.25, 0.0});
    AdaptiveStrategy strategy(adaptive(40 * 20 * 30 + 17), 40, 20);
    Accumulator merged(40, 20);
    ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
    EXPECT_EQ(merged.total_samples(), 40u * 20 * 30 + 17);
    for (size_t i = 0; i < merged.pixel_count(); ++i) {
        ASSERT_GE(merged.samples(i), 30u);
        ASSERT_LE(merged.samples(i), 31u);
    }
}

TEST(Adaptive, ABudgetBelowTheInitialPassShrinksIt) {
    AdaptiveStrategy strategy(adaptive(20 * 20 * 5 + 3), 20, 20);
    EXPECT_EQ(strategy.initial_spp(), 5u);
    const SyntheticImage image(20, 20, 1, {0.5, 0.3});
    Accumulator merged(20, 20);
    ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
    EXPECT_EQ(merged.total_samples(), 20u * 20 * 5 + 3);
}

TEST(Adaptive, MaxSppCapsEveryPixelAndReportsWhatItCouldNotSpend) {
    StrategyParams p = adaptive(1024 * 100, 10, 1);
    p.max_spp = 64;
    const SyntheticImage image = graded_image();
    AdaptiveStrategy strategy(p, 64, 16);
    Accumulator merged(64, 16);
    ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
    for (size_t i = 0; i < merged.pixel_count(); ++i) ASSERT_LE(merged.samples(i), 64u);
    EXPECT_EQ(merged.total_samples(), 1024u * 64);
    EXPECT_EQ(strategy.outcome()["unspent"], 1024u * 36);
}

TEST(Adaptive, BucketVarianceIsTheRangeOfPixelLuminance) {
    Accumulator merged(2, 2);
    SampleJobResult r;
    r.rect = {0, 0, 2, 2};
    r.pixels.resize(4);
    const double value[4] = {0.1, 0.7, 0.3, 0.4};
    for (int i = 0; i < 4; ++i) {
        r.pixels[i].even[1] = value[i];  // green only: luminance = 0.715160 * value
        r.pixels[i].samples = 1;
    }
    merged.merge(r);
    EXPECT_NEAR(AdaptiveStrategy::bucket_variance(merged, {0, 0, 2, 2}), 0.715160 * 0.6,
                1e-12);
}

TEST(Adaptive, RestoredStateDeliversTheSameRounds) {
    // A remainder over kRoundSamples is delivered in two rounds; restoring between them
    // must rebuild the same allocation. Delivery rounds do not read the buffers, so they
    // are not traced here.
    const SyntheticImage image(64, 64, 3, {0.5, 0.2});
    const uint64_t budget = 4096 * (kRoundSamples / 4096 + 100);
    StrategyParams p = adaptive(budget);
    p.initial_spp = 4;
    AdaptiveStrategy a(p, 64, 64);
    Accumulator merged(64, 64);
    run_synthetic(a, image, merged, 1);
    const auto first = a.next_round(merged);
    ASSERT_TRUE(first);
    AdaptiveStrategy b(p, 64, 64);
    b.restore_state(nlohmann::json::parse(a.save_state().dump()));
    const auto second_a = a.next_round(merged), second_b = b.next_round(merged);
    ASSERT_TRUE(second_a && second_b);
    EXPECT_EQ(second_a->spp, second_b->spp);
    EXPECT_EQ(first->total() + second_a->total() + 4096u * 4, budget);
    EXPECT_FALSE(a.next_round(merged));
    EXPECT_FALSE(b.next_round(merged));
}

TEST(Adaptive, ALargeRemainderIsDeliveredInEighthsOfTheBudget) {
    // 64 kRoundSamples of budget (1024 spp at 2048x1024): delivered in rounds of an
    // eighth of it, so each pixel is merged 9 times, not 65 (rounds of kRoundSamples).
    // Restored mid-way, the rest comes in the same rounds.
    const SyntheticImage image(64, 64, 3, {0.5, 0.2});
    const uint64_t budget = 64 * kRoundSamples;
    StrategyParams p = adaptive(budget);
    p.initial_spp = 4;
    AdaptiveStrategy a(p, 64, 64);
    Accumulator merged(64, 64);
    run_synthetic(a, image, merged, 1);  // the initial pass
    uint64_t samples = 4096u * 4;
    uint32_t deliveries = 0;
    std::optional<AdaptiveStrategy> resumed;
    while (const auto round = a.next_round(merged)) {
        if (resumed) {
            const auto again = resumed->next_round(merged);
            ASSERT_TRUE(again);
            EXPECT_EQ(again->spp, round->spp);
            EXPECT_EQ(again->index, round->index);
        }
        EXPECT_LE(round->total(), budget / 8 + 4096);  // a pixel's rounding at most
        samples += round->total();
        if (++deliveries == 3) {
            resumed.emplace(p, 64, 64);
            resumed->restore_state(nlohmann::json::parse(a.save_state().dump()));
        }
    }
    EXPECT_FALSE(resumed->next_round(merged));
    EXPECT_EQ(deliveries, 8u);
    EXPECT_EQ(samples, budget);
}

}  // namespace
}  // namespace aliquot
