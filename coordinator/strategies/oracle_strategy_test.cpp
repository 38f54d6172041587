#include "oracle_strategy.h"

#include <gtest/gtest.h>

#include <cmath>

#include "optimal_strategy.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

// Four vertical bands of 16 columns whose noise doubles from one band to the next.
SyntheticImage banded_image() {
    SyntheticImage image(64, 64, 21);
    for (uint32_t y = 0; y < 64; ++y)
        for (uint32_t x = 0; x < 64; ++x)
            image.at(x, y) = {0.5, 0.1 * double(1 << (x / 16))};
    return image;
}

StrategyParams oracle(const SyntheticImage& image, uint64_t budget) {
    StrategyParams p;
    p.method = "oracle";
    p.budget = budget;
    auto sigma = std::make_shared<std::vector<float>>(image.pixel_count());
    for (size_t i = 0; i < sigma->size(); ++i) (*sigma)[i] = float(image.sigma(i));
    p.true_sigma = sigma;
    return p;
}

TEST(Oracle, WithTheSyntheticSigmaGivesTheAnalyticOptimum) {
    const SyntheticImage image = banded_image();
    const uint64_t budget = 4096 * 64;
    const auto strategy = make_strategy(oracle(image, budget), 64, 64);
    Accumulator merged(64, 64);
    ASSERT_TRUE(run_synthetic(*strategy, image, merged).finished);
    ASSERT_EQ(merged.total_samples(), budget);
    // No floor binds (the quietest band gets ~33 spp), so n_i = B sigma_i^(2/3) /
    // sum_j sigma_j^(2/3): the bands' counts in the ratio 1 : 2^(2/3) : 4^(2/3) :
    // 8^(2/3).
    double norm = 0;
    for (size_t i = 0; i < 4096; ++i) norm += std::cbrt(image.sigma(i) * image.sigma(i));
    double f = 0, f_best = 0, f_uniform = 0;
    for (size_t i = 0; i < 4096; ++i) {
        const double s = image.sigma(i);
        const double best = double(budget) * std::cbrt(s * s) / norm;
        EXPECT_NEAR(double(merged.samples(i)), best, 1.0) << "pixel " << i;
        f += s / std::sqrt(double(merged.samples(i)));
        f_uniform += s / std::sqrt(double(budget) / 4096);
    }
    // ... and the expected error is the bound (sum sigma^(2/3))^(3/2) / sqrt(B), which
    // Hölder's inequality puts below uniform's.
    f_best = std::pow(norm, 1.5) / std::sqrt(double(budget));
    EXPECT_NEAR(f / f_best, 1.0, 1e-3);
    EXPECT_LT(f_best, f_uniform);
}

TEST(Oracle, DecidesFromSigmaAloneNotFromTheSamples) {
    // Fireflies the oracle's sigma does not know of change nothing in its allocation.
    SyntheticImage image = banded_image();
    const auto quiet = make_strategy(oracle(image, 64 * 64 * 32), 64, 64);
    image.at(3, 3).firefly_probability = 0.2;
    image.at(3, 3).firefly_value = 100;
    const auto noisy = make_strategy(oracle(banded_image(), 64 * 64 * 32), 64, 64);
    Accumulator a(64, 64), b(64, 64);
    run_synthetic(*quiet, banded_image(), a);
    run_synthetic(*noisy, image, b);
    for (size_t i = 0; i < 4096; ++i) ASSERT_EQ(a.samples(i), b.samples(i));
}

TEST(Oracle, KeepsTheFloorWhereSigmaIsZero) {
    SyntheticImage image(16, 16, 5, {0.5, 0.0});
    for (uint32_t x = 0; x < 8; ++x) image.at(x, 0).sigma = 0.5;
    StrategyParams p = oracle(image, 16 * 16 * 16);
    p.min_spp = 2;
    const auto strategy = make_strategy(p, 16, 16);
    Accumulator merged(16, 16);
    ASSERT_TRUE(run_synthetic(*strategy, image, merged).finished);
    EXPECT_EQ(merged.total_samples(), 16u * 16 * 16);
    EXPECT_EQ(merged.samples(16 * 8), 2u);  // sigma 0: the floor only
    EXPECT_GT(merged.samples(0), 100u);
}

TEST(Oracle, ResumesFromItsStateWithTheSameRounds) {
    const SyntheticImage image = banded_image();
    // A budget above one round's kRoundSamples, so the render has several rounds.
    const uint64_t budget = 64 * 64 * (kRoundSamples / (64 * 64) + 500);
    OracleStrategy whole(oracle(image, budget), 64, 64);
    OracleStrategy first(oracle(image, budget), 64, 64);
    Accumulator merged(64, 64);
    const std::optional<Round> r0 = whole.next_round(merged);
    ASSERT_TRUE(r0);
    first.next_round(merged);
    OracleStrategy resumed(oracle(image, budget), 64, 64);
    resumed.restore_state(first.save_state());
    const std::optional<Round> a = whole.next_round(merged),
                               b = resumed.next_round(merged);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->spp, b->spp);
    EXPECT_EQ(a->index, 1u);
}

TEST(Oracle, ALargeBudgetIsDeliveredInEighths) {
    // 64 kRoundSamples of budget: rounds of an eighth of it, so each pixel is merged 8
    // times, not 64 (rounds of kRoundSamples), and the rounds add up to the budget.
    const uint64_t budget = 64 * kRoundSamples;
    OracleStrategy strategy(oracle(banded_image(), budget), 64, 64);
    Accumulator merged(64, 64);  // the oracle reads nothing merged
    uint32_t rounds = 0;
    uint64_t samples = 0;
    while (const auto round = strategy.next_round(merged)) {
        EXPECT_EQ(round->index, rounds++);
        samples += round->total();
    }
    EXPECT_EQ(rounds, 8u);
    EXPECT_EQ(samples, budget);
}

}  // namespace
}  // namespace aliquot
