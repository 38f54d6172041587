#include "uniform_strategy.h"

#include <gtest/gtest.h>

#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

StrategyParams uniform_budget(uint64_t budget) {
    StrategyParams p;
    p.method = "uniform";
    p.budget = budget;
    return p;
}

TEST(Uniform, GivesEveryPixelFloorOfBudgetOverPixels) {
    // 37 x 11 = 407 pixels; 407 * 9 + 406 samples is one short of 10 per pixel.
    const SyntheticImage image(37, 11, 3, {0.5, 0.2});
    auto strategy = make_strategy(uniform_budget(407 * 9 + 406), 37, 11);
    Accumulator merged(37, 11);
    ASSERT_TRUE(run_synthetic(*strategy, image, merged).finished);
    for (size_t i = 0; i < merged.pixel_count(); ++i) ASSERT_EQ(merged.samples(i), 9u);
    EXPECT_EQ(strategy->planned_samples(), 407u * 9);
}

TEST(Uniform, ProgressiveRoundsAddUpToSpp) {
    UniformStrategy strategy(8, 8, 100);
    Accumulator merged(8, 8);
    uint32_t sum = 0, rounds = 0;
    while (auto round = strategy.next_round(merged)) {
        sum += round->spp[0];
        for (uint32_t s : round->spp) ASSERT_EQ(s, round->spp[0]);
        EXPECT_EQ(round->index, rounds++);
    }
    EXPECT_EQ(sum, 100u);
    EXPECT_EQ(rounds, 1u);  // a small image's first round holds kFirstRoundSamples
}

TEST(Uniform, RoundsDoubleFromAboutKFirstRoundSamples) {
    const size_t pixels = 1 << 16;
    const uint32_t first = uint32_t(kFirstRoundSamples / pixels);
    EXPECT_EQ(UniformStrategy::round_spp(0, 4096, pixels), first);
    EXPECT_EQ(UniformStrategy::round_spp(first, 4096, pixels), first);
    EXPECT_EQ(UniformStrategy::round_spp(2 * first, 4096, pixels), 2 * first);
    EXPECT_EQ(UniformStrategy::round_spp(0, 4096, 4096 * 4096), 1u);  // never below 1
}

TEST(Uniform, RoundsOfALargeImageStayNearKRoundSamples) {
    EXPECT_EQ(UniformStrategy::round_spp(100, 1000, 8192 * 8192), 1u);  // never below 1
    EXPECT_EQ(UniformStrategy::round_spp(100, 1000, 4096 * 4096), 2u);
    EXPECT_EQ(UniformStrategy::round_spp(100, 1000, 1920 * 1080), 16u);
    EXPECT_EQ(UniformStrategy::round_spp(100, 1000, 1 << 20), 32u);
    EXPECT_EQ(UniformStrategy::round_spp(512, 1000, 1024),
              488u);  // the last, partial round
}

TEST(Uniform, RestoredStateContinuesWhereItStopped) {
    UniformStrategy a(4, 4, 50), b(4, 4, 50);
    Accumulator merged(4, 4);
    a.next_round(merged);
    a.next_round(merged);
    b.restore_state(a.save_state());
    for (auto ra = a.next_round(merged), rb = b.next_round(merged); ra || rb;
         ra = a.next_round(merged), rb = b.next_round(merged)) {
        ASSERT_TRUE(ra && rb);
        EXPECT_EQ(ra->spp, rb->spp);
        EXPECT_EQ(ra->index, rb->index);
    }
}

TEST(Uniform, MaxSppCapsTheSamplesPerPixel) {
    StrategyParams p = uniform_budget(64 * 100);
    p.max_spp = 7;
    EXPECT_EQ(make_strategy(p, 8, 8)->planned_samples(), 64u * 7);
}

}  // namespace
}  // namespace aliquot
