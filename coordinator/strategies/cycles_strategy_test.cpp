#include "cycles_strategy.h"

#include <gtest/gtest.h>

#include "round_cutter.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

StrategyParams cycles(double threshold) {
    StrategyParams p;
    p.method = "cycles";
    p.noise_threshold = threshold;
    return p;
}

TEST(Cycles, AutomaticMinSamplesFollowTheThreshold) {
    EXPECT_EQ(CyclesStrategy::automatic_min_samples(0.1), 32u);
    EXPECT_EQ(CyclesStrategy::automatic_min_samples(0.01), 64u);
    EXPECT_EQ(CyclesStrategy::automatic_min_samples(0.001), 128u);
    EXPECT_EQ(CyclesStrategy::automatic_min_samples(1e6), 4u);  // never below 4
    EXPECT_EQ(CyclesStrategy(cycles(0.01), 4, 4).min_samples(), 64u);
}

TEST(Cycles, StopsPixelsBelowTheThresholdAndSamplesTheOthersToTheCap) {
    // Left half noiseless, right half very noisy: the left stops at the minimum samples
    // except the column next to the right half, which the dilation keeps sampling.
    SyntheticImage image(16, 8, 7, {0.5, 0.0});
    for (uint32_t y = 0; y < 8; ++y)
        for (uint32_t x = 8; x < 16; ++x) image.at(x, y).sigma = 2.0;
    StrategyParams p = cycles(0.01);
    p.adaptive_min_samples = 8;
    p.adaptive_step = 4;
    p.max_spp = 64;
    const auto strategy = make_strategy(p, 16, 8);
    Accumulator merged(16, 8);
    ASSERT_TRUE(run_synthetic(*strategy, image, merged).finished);
    for (uint32_t y = 0; y < 8; ++y) {
        for (uint32_t x = 0; x < 7; ++x) EXPECT_EQ(merged.samples(y * 16 + x), 8u) << x;
        for (uint32_t x = 7; x < 16; ++x) EXPECT_EQ(merged.samples(y * 16 + x), 64u) << x;
    }
    EXPECT_EQ(strategy->outcome()["stopped_by"], "max_spp");
}

TEST(Cycles, MeasuresTheErrorFromTheTwoHalfImagesRelativeToBrightness) {
    Accumulator merged(1, 1);
    SampleJobResult r;
    r.rect = {0, 0, 1, 1};
    r.pixels.resize(1);
    // Two samples, 1 (even index) and 3 (odd index) per channel: the full mean is 2,
    // the even half's 1, so the error is 3 * |2 - 1| / sqrt(3 * 2).
    for (int c = 0; c < 3; ++c) {
        r.pixels[0].even[c] = 1;
        r.pixels[0].odd[c] = 3;
    }
    r.pixels[0].samples = 2;
    merged.merge(r);
    EXPECT_NEAR(CyclesStrategy::pixel_error(merged, 0), 3.0 / std::sqrt(6.0), 1e-4);
}

TEST(Cycles, DilatesTheConvergedMaskSoNeighboursOfUnconvergedPixelsKeepSampling) {
    std::vector<bool> converged(7 * 5, true);
    converged[2 * 7 + 3] = false;  // the centre of a 7x5 image
    converged[0] = false;          // and a corner
    const std::vector<bool> out = CyclesStrategy::dilate_unconverged(converged, 7, 5);
    for (uint32_t y = 0; y < 5; ++y)
        for (uint32_t x = 0; x < 7; ++x) {
            const bool near_centre = x >= 2 && x <= 4 && y >= 1 && y <= 3;
            const bool near_corner = x <= 1 && y <= 1;
            EXPECT_EQ(out[y * 7 + x], !(near_centre || near_corner)) << x << "," << y;
        }
}

TEST(Cycles, ARoundAfterTheMinimumSamplesOnlyTheNoisyPixelAndItsNeighbours) {
    SyntheticImage image(9, 9, 3, {0.5, 0.0});
    image.at(4, 4).sigma = 1.0;
    StrategyParams p = cycles(0.01);
    p.adaptive_min_samples = 16;
    p.adaptive_step = 16;
    CyclesStrategy strategy(p, 9, 9);
    Accumulator merged(9, 9);
    uint32_t rounds = 0;
    run_synthetic(
        strategy, image, merged, 2, [&](const Round& round, const Accumulator&) {
            if (++rounds != 2) return;
            for (uint32_t y = 0; y < 9; ++y)
                for (uint32_t x = 0; x < 9; ++x) {
                    const bool near = x >= 3 && x <= 5 && y >= 3 && y <= 5;
                    EXPECT_EQ(round.spp[y * 9 + x], near ? 16u : 0u) << x << "," << y;
                }
        });
    EXPECT_EQ(rounds, 2u);
}

TEST(Cycles, ABudgetCapsTheTotalAndEndsTheRender) {
    SyntheticImage image(16, 16, 9, {0.5, 1.0});
    StrategyParams p = cycles(0.0001);  // unreachable
    p.budget = 16 * 16 * 100 + 37;
    const auto strategy = make_strategy(p, 16, 16);
    Accumulator merged(16, 16);
    ASSERT_TRUE(run_synthetic(*strategy, image, merged).finished);
    EXPECT_EQ(merged.total_samples(), p.budget);
    EXPECT_EQ(strategy->outcome()["stopped_by"], "max_samples");
}

TEST(Cycles, ResumesFromItsStateWithTheSameDecisions) {
    SyntheticImage image(16, 16, 9);
    for (uint32_t y = 0; y < 16; ++y)
        for (uint32_t x = 0; x < 16; ++x) image.at(x, y) = {0.5, 0.02 * x};
    StrategyParams p = cycles(0.02);
    p.adaptive_step = 8;
    CyclesStrategy whole(p, 16, 16);
    Accumulator merged(16, 16);
    run_synthetic(whole, image, merged, 2);
    CyclesStrategy resumed(p, 16, 16);
    resumed.restore_state(whole.save_state());
    const std::optional<Round> a = whole.next_round(merged);
    const std::optional<Round> b = resumed.next_round(merged);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->spp, b->spp);
    EXPECT_EQ(a->index, b->index);
}

TEST(Cycles, JudgingOnlyThePixelsThatGotSamplesPlansAsJudgingEveryPixel) {
    // A strategy keeps each pixel's judgement until the pixel gets samples; one restored
    // from its state judges every pixel afresh. Asked at every round end, with pixels
    // stopping, and neighbours of pixels whose error rose sampled again, they plan alike.
    SyntheticImage image(40, 30, 5);
    for (uint32_t y = 0; y < 30; ++y)
        for (uint32_t x = 0; x < 40; ++x)
            image.at(x, y) = {0.3 + 0.01 * y, (x / 5 + y / 5) % 3 ? 0.01 * (x % 4) : 0.4};
    StrategyParams p = cycles(0.02);
    p.adaptive_min_samples = 8;
    p.adaptive_step = 4;
    p.max_spp = 256;
    CyclesStrategy kept(p, 40, 30);
    Accumulator merged(40, 30);
    uint32_t rounds = 0;
    for (; rounds < 100; ++rounds) {
        CyclesStrategy afresh(p, 40, 30);
        afresh.restore_state(kept.save_state());
        const std::optional<Round> a = kept.next_round(merged);
        const std::optional<Round> b = afresh.next_round(merged);
        ASSERT_EQ(a.has_value(), b.has_value()) << "round " << rounds;
        if (!a) break;
        ASSERT_EQ(a->spp, b->spp) << "round " << rounds;
        for (const SampleJob& job : cut_round(*a, merged)) merged.merge(image.trace(job));
    }
    EXPECT_GT(rounds, 10u);  // pixels stopped and others went on
    EXPECT_GT(kept.outcome()["converged_fraction"].get<double>(), 0.25);
}

}  // namespace
}  // namespace aliquot
