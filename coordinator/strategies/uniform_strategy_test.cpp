#include "uniform_strategy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

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

TEST(Uniform, RoundsGrowEightfoldFromAboutKFirstRoundSamples) {
    const size_t pixels = 1 << 16;
    const uint32_t first = uint32_t(kFirstRoundSamples / pixels);
    // A budget whose cap (an eighth: 8192 spp) does not bind: the render so far grows
    // eightfold a round.
    EXPECT_EQ(UniformStrategy::round_spp(0, 65536, pixels), first);
    EXPECT_EQ(UniformStrategy::round_spp(first, 65536, pixels), 7 * first);
    EXPECT_EQ(UniformStrategy::round_spp(8 * first, 65536, pixels), 56 * first);
    EXPECT_EQ(UniformStrategy::round_spp(0, 4096, 4096 * 4096), 1u);  // never below 1
}

TEST(Uniform, RoundsOfASmallBudgetStayNearKRoundSamples) {
    // Budgets of at most 8 kRoundSamples: rounds of kRoundSamples, as before the cap grew
    // with the budget.
    EXPECT_EQ(UniformStrategy::round_spp(2, 4, 8192 * 8192), 1u);  // never below 1
    EXPECT_EQ(UniformStrategy::round_spp(4, 16, 4096 * 4096), 2u);
    EXPECT_EQ(UniformStrategy::round_spp(100, 128, 1920 * 1080), 16u);
    EXPECT_EQ(UniformStrategy::round_spp(100, 256, 1 << 20), 32u);
    EXPECT_EQ(UniformStrategy::round_spp(512, 1000, 1024),
              488u);  // the last, partial round
}

TEST(Uniform, RoundsGrowWithTheBudget) {
    // Above 8 kRoundSamples a round holds up to an eighth of the budget, so that a pixel
    // is merged about log2(spp) + 7 times, not spp / 16 times at 1920x1080.
    EXPECT_EQ(round_samples(kRoundSamples), kRoundSamples);
    EXPECT_EQ(round_samples(8 * kRoundSamples), kRoundSamples);
    EXPECT_EQ(round_samples(64 * kRoundSamples), 8 * kRoundSamples);
    EXPECT_EQ(UniformStrategy::round_spp(2, 1000, 1920 * 1080), 14u);     // still growing
    EXPECT_EQ(UniformStrategy::round_spp(100, 1000, 1920 * 1080), 125u);  // an eighth
    EXPECT_EQ(UniformStrategy::round_spp(256, 1024, 1920 * 1080), 128u);  // an eighth
    EXPECT_EQ(UniformStrategy::round_spp(512, 4096, 4096 * 4096), 512u);
}

// The spp of each round of a render of `spp` over `pixels`, from round_spp as next_round
// hands them out.
std::vector<uint32_t> schedule(uint32_t spp, size_t pixels) {
    std::vector<uint32_t> rounds;
    for (uint32_t done = 0; done < spp; done += rounds.back())
        rounds.push_back(UniformStrategy::round_spp(done, spp, pixels));
    return rounds;
}

TEST(Uniform, A1080pRenderOf1024SppIsMergedTenTimes) {
    // 2, 14, 112 spp, then seven of 128: 10 rounds where doubling rounds were 14 and
    // rounds of at most kRoundSamples (16 spp here) 67.
    const std::vector<uint32_t> rounds = schedule(1024, 1920 * 1080);
    EXPECT_EQ(rounds,
              (std::vector<uint32_t>{2, 14, 112, 128, 128, 128, 128, 128, 128, 128}));
    // 2, 14, then three of 16 at 64 spp, where doubling rounds were 7.
    EXPECT_EQ(schedule(64, 1920 * 1080), (std::vector<uint32_t>{2, 14, 16, 16, 16}));
    // At most log2(spp) + 7 rounds for every budget, at every size; the rounds add up to
    // the spp.
    for (const size_t pixels :
         {size_t(64 * 64), size_t(1920 * 1080), size_t(4096 * 2160)})
        for (uint32_t spp = 1; spp <= 16384; spp = spp * 3 / 2 + 1) {
            const std::vector<uint32_t> r = schedule(spp, pixels);
            uint64_t sum = 0;
            for (uint32_t s : r) sum += s;
            EXPECT_EQ(sum, spp) << pixels << " pixels, " << spp << " spp";
            EXPECT_LE(double(r.size()), std::log2(double(spp)) + 7.0)
                << pixels << " pixels, " << spp << " spp";
        }
}

TEST(Uniform, ARenderOf1024SppRestoredMidWayGoesOnInTheSameRounds) {
    const uint32_t w = 1920, h = 1080;
    UniformStrategy whole(w, h, 1024), first(w, h, 1024);
    Accumulator merged(1, 1);      // uniform reads nothing merged
    for (int k = 0; k < 5; ++k) {  // past the growth, into the rounds of 128 spp
        ASSERT_TRUE(whole.next_round(merged));
        ASSERT_TRUE(first.next_round(merged));
    }
    UniformStrategy resumed(w, h, 1024);
    resumed.restore_state(nlohmann::json::parse(first.save_state().dump()));
    uint32_t rounds = 5;
    uint64_t samples = 0;
    for (auto a = whole.next_round(merged), b = resumed.next_round(merged); a || b;
         a = whole.next_round(merged), b = resumed.next_round(merged)) {
        ASSERT_TRUE(a && b);
        EXPECT_EQ(a->index, rounds++);
        EXPECT_EQ(b->index, a->index);
        EXPECT_EQ(b->spp, a->spp);
        samples += b->total();
    }
    EXPECT_EQ(rounds, 10u);
    EXPECT_EQ(samples, uint64_t(w) * h * (1024 - 128 - 2 * 128));
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
