#include "optimal_strategy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <thread>

#include "round_cutter.h"

#include "strategy_params.h"
#include "synthetic_source.h"
#include "uniform_strategy.h"

namespace aliquot {
namespace {

StrategyParams optimal(uint64_t budget, const char* method = "optimal") {
    StrategyParams p;
    p.method = method;
    p.budget = budget;
    return p;
}

// Four vertical bands of 16 columns whose noise doubles from one band to the next.
SyntheticImage banded_image() {
    SyntheticImage image(64, 64, 21);
    for (uint32_t y = 0; y < 64; ++y)
        for (uint32_t x = 0; x < 64; ++x)
            image.at(x, y) = {0.5, 0.1 * double(1 << (x / 16))};
    return image;
}

// The counts of every round `strategy` gives, driven round by round on `image`.
std::vector<std::vector<uint32_t>> rounds_of(OptimalStrategy& strategy,
                                             const SyntheticImage& image,
                                             Accumulator& merged) {
    std::vector<std::vector<uint32_t>> rounds;
    run_synthetic(strategy, image, merged, 100,
                  [&](const Round& r, const Accumulator&) { rounds.push_back(r.spp); });
    return rounds;
}

// sum_i sigma_i / sqrt(n_i): the expected mean absolute error up to a constant.
double expected_error(const Accumulator& merged, const SyntheticImage& image) {
    double f = 0;
    for (size_t i = 0; i < merged.pixel_count(); ++i)
        f += image.sigma(i) / std::sqrt(double(merged.samples(i)));
    return f;
}

// Renders the banded image (four bands of known sigma) with `p` and checks that each
// band's samples are within 5 % of the analytic optimum's under the same floor.
void expect_bands_near_the_optimum(const StrategyParams& p) {
    const SyntheticImage image = banded_image();
    const uint64_t budget = p.budget;
    OptimalStrategy strategy(p, 64, 64, false);
    Accumulator merged(64, 64);
    ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
    ASSERT_EQ(merged.total_samples(), budget);
    std::vector<double> weight(4096);
    for (size_t i = 0; i < 4096; ++i)
        weight[i] = std::cbrt(image.sigma(i) * image.sigma(i));
    // The optimum under the same floor: min_spp, or floor_fraction of the mean spp.
    const double floor =
        std::max(double(p.min_spp), std::floor(p.floor_fraction * double(budget) / 4096));
    const auto best =
        OptimalStrategy::optimal_counts(weight, {}, double(budget), floor, 1e9);
    for (uint32_t band = 0; band < 4; ++band) {
        double got = 0, want = 0;
        for (uint32_t y = 0; y < 64; ++y)
            for (uint32_t x = band * 16; x < band * 16 + 16; ++x) {
                got += double(merged.samples(y * 64 + x));
                want += best[y * 64 + x];
            }
        EXPECT_NEAR(got / want, 1.0, 0.05) << "band " << band;
    }
}

// 5x5 pixels of 2 samples each, all zero but the centre's, whose odd sample is 10: a
// firefly (sample variance 50) among pixels that have drawn none.
Accumulator one_firefly() {
    Accumulator merged(5, 5);
    SampleJobResult r;
    r.rect = {0, 0, 5, 5};
    r.pixels.resize(25);
    for (PixelSums& p : r.pixels) p.samples = 2;
    for (int c = 0; c < 3; ++c) r.pixels[12].odd[c] = 10;
    r.pixels[12].sum_sq_luminance = 100;
    merged.merge(r);
    return merged;
}

TEST(Optimal, OptimalCountsMeetTheLagrangeConditions) {
    const std::vector<double> w = {0.01, 0.5, 1, 2, 4, 100};
    const auto n = OptimalStrategy::optimal_counts(w, {}, 200, 4, 60);
    double sum = 0;
    for (double v : n) sum += v;
    EXPECT_NEAR(sum, 200, 1e-9);
    EXPECT_DOUBLE_EQ(n[0], 4);   // floor
    EXPECT_DOUBLE_EQ(n[5], 60);  // cap
    const double mu = n[3] / w[3];
    for (size_t i = 1; i < 5; ++i)
        EXPECT_NEAR(n[i], std::clamp(mu * w[i], 4.0, 60.0), 1e-9);
}

// Pixels of weight 0 stay at their floor; a total beyond what the others can take at
// their caps puts them all there, at once rather than after a long search.
TEST(Optimal, OptimalCountsCapEveryWeightedPixelWhenTheTotalIsOutOfReach) {
    const auto n = OptimalStrategy::optimal_counts({0, 1, 2}, {}, 25, 1, 10);
    EXPECT_EQ(n, (std::vector<double>{1, 10, 10}));
}

// Weights hundreds of orders of magnitude apart: the search narrows its bracket by
// orders of magnitude and still lands on the root's piece.
TEST(Optimal, OptimalCountsFindTheRootOverWeightsOfEveryMagnitude) {
    const std::vector<double> w = {1e-300, 1e-150, 1, 1e150, 1e300};
    const auto n = OptimalStrategy::optimal_counts(w, {}, 250, 0, 100);
    EXPECT_NEAR(n[0] + n[1] + n[2] + n[3] + n[4], 250, 1e-9);
    EXPECT_NEAR(n[2], 50, 1e-9);
    EXPECT_EQ(n[3], 100);
    EXPECT_EQ(n[4], 100);
}

TEST(Optimal, OptimalCountsWithCostsSpendTheCostBudget) {
    const std::vector<double> w = {1, 1, 1}, c = {1, 2, 4};
    const auto n = OptimalStrategy::optimal_counts(w, c, 70, 0, 1e9);
    EXPECT_NEAR(n[0] * 1 + n[1] * 2 + n[2] * 4, 70, 1e-9);
    EXPECT_NEAR(n[0], 10, 1e-9);
}

// Enough pixels that the pieces' sums span bands and the search takes several steps;
// many equal weights, so many pieces' breakpoints coincide too.
TEST(Optimal, OptimalCountsOverManyPixelsMeetTheLagrangeConditions) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> spread(-6, 6);
    const size_t n = 20000;
    std::vector<double> w(n), c(n);
    for (size_t i = 0; i < n; ++i) {
        w[i] = i % 3 == 0 ? 1.0 : std::exp(spread(rng));
        c[i] = 1 + double(i % 7);
    }
    for (const bool with_costs : {false, true}) {
        const std::vector<double> costs = with_costs ? c : std::vector<double>{};
        const double lo = 2, hi = 500;
        double floor_cost = 0;
        for (size_t i = 0; i < n; ++i) floor_cost += (with_costs ? c[i] : 1) * lo;
        const double total = floor_cost * 6;
        const auto counts = OptimalStrategy::optimal_counts(w, costs, total, lo, hi);
        double spent = 0, mu = -1;
        for (size_t i = 0; i < n; ++i) {
            spent += (with_costs ? c[i] : 1) * counts[i];
            if (counts[i] > lo && counts[i] < hi) mu = counts[i] / w[i];
        }
        EXPECT_NEAR(spent / total, 1.0, 1e-9);
        ASSERT_GT(mu, 0);
        for (size_t i = 0; i < n; ++i)
            ASSERT_NEAR(counts[i], std::clamp(mu * w[i], lo, hi), 1e-6 * counts[i]) << i;
    }
}

TEST(Optimal, AllocationMatchesTheAnalyticOptimumForKnownVariances) {
    expect_bands_near_the_optimum(optimal(4096 * 64));
}

TEST(Optimal, ExpectedErrorBeatsUniformByThePredictedRatio) {
    const SyntheticImage image = banded_image();
    const uint64_t budget = 4096 * 64;
    OptimalStrategy strategy(optimal(budget), 64, 64, false);
    Accumulator merged(64, 64);
    run_synthetic(strategy, image, merged);
    // Uniform: sum sigma * sqrt(N / B). Optimum: (sum sigma^(2/3))^(3/2) / sqrt(B).
    double sum_sigma = 0, sum_23 = 0;
    for (size_t i = 0; i < 4096; ++i) {
        sum_sigma += image.sigma(i);
        sum_23 += std::cbrt(image.sigma(i) * image.sigma(i));
    }
    const double uniform = sum_sigma * std::sqrt(4096.0 / double(budget));
    const double predicted = std::pow(sum_23, 1.5) / std::sqrt(double(budget)) / uniform;
    const double measured = expected_error(merged, image) / uniform;
    EXPECT_LT(predicted, 0.95);
    EXPECT_NEAR(measured, predicted, 0.01 * predicted);
}

TEST(Optimal, MeasuredErrorBeatsUniformWithAFewHighVariancePixels) {
    SyntheticImage image(64, 64, 8, {0.5, 0.05});
    for (uint32_t i = 0; i < 4096; i += 97) image.at(i % 64, i / 64).sigma = 5.0;
    const uint64_t budget = 4096 * 16;
    Accumulator uniform_merged(64, 64), optimal_merged(64, 64);
    UniformStrategy uniform(64, 64, 16);
    OptimalStrategy strategy(optimal(budget), 64, 64, false);
    run_synthetic(uniform, image, uniform_merged);
    run_synthetic(strategy, image, optimal_merged);
    const double e_uniform = mean_absolute_error(uniform_merged, image);
    const double e_optimal = mean_absolute_error(optimal_merged, image);
    // Predicted ratio of expected errors here is about 0.7.
    EXPECT_LT(e_optimal, 0.8 * e_uniform) << e_optimal << " vs " << e_uniform;
}

TEST(Optimal, SpendsExactlyItsBudget) {
    const SyntheticImage image = banded_image();
    for (uint64_t budget : {4096u * 4, 4096u * 9 + 1, 4096u * 33 + 4095}) {
        OptimalStrategy strategy(optimal(budget), 64, 64, false);
        Accumulator merged(64, 64);
        ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
        EXPECT_EQ(merged.total_samples(), budget);
        EXPECT_EQ(strategy.outcome()["unspent"], 0);
    }
}

TEST(Optimal, EveryPixelGetsTheFloorAndNoneExceedsTheCap) {
    StrategyParams p = optimal(4096 * 32);
    p.min_spp = 8;
    p.max_spp = 100;
    const SyntheticImage image = banded_image();
    OptimalStrategy strategy(p, 64, 64, false);
    Accumulator merged(64, 64);
    ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
    for (size_t i = 0; i < 4096; ++i) {
        ASSERT_GE(merged.samples(i), 8u);
        ASSERT_LE(merged.samples(i), 100u);
    }
}

TEST(Optimal, AZeroVarianceEstimateIsRaisedToItsNeighbourhood) {
    // 5x5 pixels with sample variance 2 (values 0 and 2 on even and odd samples) except
    // the centre, whose two samples agree.
    Accumulator merged(5, 5);
    SampleJobResult r;
    r.rect = {0, 0, 5, 5};
    r.pixels.resize(25);
    for (size_t i = 0; i < 25; ++i) {
        PixelSums& p = r.pixels[i];
        const double odd = i == 12 ? 0.0 : 2.0;
        for (int c = 0; c < 3; ++c) p.odd[c] = odd;
        p.sum_sq_luminance = odd * odd;
        p.samples = 2;
    }
    merged.merge(r);
    const auto sigma = OptimalStrategy::sigma_estimates(merged);
    EXPECT_NEAR(sigma[0], std::sqrt(2.0), 1e-5);
    EXPECT_NEAR(sigma[12], std::sqrt(0.5 * 2.0), 1e-5);
}

TEST(Optimal, AnIsolatedNoisyPixelDoesNotRaiseItsNeighbours) {
    const Accumulator merged = one_firefly();
    const auto sigma = OptimalStrategy::sigma_estimates(merged);
    EXPECT_GT(sigma[12], 5.0);
    EXPECT_EQ(sigma[11], 0.0);  // the image median is 0 too
}

TEST(Optimal, PooledSigmaSpreadsAFireflyOverItsNeighbourhood) {
    // The firefly pixel of the test above (sample variance 50): with sigma_radius 1 it
    // and its eight neighbours share 50 / 9; pixels beyond its window keep 0.
    const Accumulator merged = one_firefly();
    const auto own = OptimalStrategy::sigma_estimates(merged);
    const auto pooled = OptimalStrategy::sigma_estimates(merged, 1);
    EXPECT_NEAR(own[12], std::sqrt(50.0), 1e-9);
    EXPECT_NEAR(pooled[12], std::sqrt(50.0 / 9), 1e-9);
    EXPECT_NEAR(pooled[6], std::sqrt(50.0 / 9), 1e-9);
    EXPECT_EQ(pooled[0], 0.0);  // its 2x2 window misses the firefly
    // At the edge the window is clipped, not padded: pixel 7's 3x3 holds the firefly.
    EXPECT_NEAR(pooled[7], std::sqrt(50.0 / 9), 1e-9);
    EXPECT_NEAR(pooled[2], std::sqrt(0.0), 1e-9);
}

TEST(Optimal, APriorShrinksFewSamplesTowardsThePoolAndLetsManySpeakForThemselves) {
    // The firefly pixel (variance 50, 2 samples: 1 degree of freedom) with a prior of 8
    // samples: (1 * 50 + 8 * 50/9) / 9. A neighbour with variance 0: (0 + 8 * 50/9) / 9.
    Accumulator merged = one_firefly();
    const auto shrunk = OptimalStrategy::sigma_estimates(merged, 1, 8);
    EXPECT_NEAR(shrunk[12], std::sqrt((50.0 + 8 * 50.0 / 9) / 9), 1e-9);
    EXPECT_NEAR(shrunk[11], std::sqrt((8 * 50.0 / 9) / 9), 1e-9);
    // With many samples the pixel's own variance dominates the same prior.
    SampleJobResult more;
    more.rect = {0, 0, 5, 5};
    more.pixels.resize(25);
    for (PixelSums& p : more.pixels) p.samples = 998;
    for (int c = 0; c < 3; ++c) more.pixels[12].odd[c] = 4990;  // 499 odd samples of 10
    more.pixels[12].sum_sq_luminance = 49900;
    merged.merge(more);
    const auto many = OptimalStrategy::sigma_estimates(merged, 1, 8);
    const auto own = OptimalStrategy::sigma_estimates(merged);
    EXPECT_NEAR(many[12] / own[12], 1.0, 0.01);
}

TEST(Optimal, PooledSigmaStillFindsTheOptimumOnSmoothNoise) {
    // On the banded image (noise constant over 16-column bands) pooling over 3x3 moves
    // only the band edges: the bands' totals stay within 5 % of the analytic optimum.
    StrategyParams p = optimal(4096 * 64);
    p.sigma_radius = 1;
    expect_bands_near_the_optimum(p);
}

TEST(Optimal, AFloorFractionPilotsAndFloorsAtThatShareOfTheMeanSpp) {
    // Banded image, mean 32 spp: with floor_fraction 0.5 the pilot is 16 spp everywhere
    // (in two rounds of 8: plan_ahead 1 splits it) and no pixel ends below it; without,
    // the quietest band ends below 16.
    const SyntheticImage image = banded_image();
    StrategyParams p = optimal(4096 * 32);
    p.floor_fraction = 0.5;
    OptimalStrategy floored(p, 64, 64, false);
    Accumulator merged(64, 64);
    std::vector<std::vector<uint32_t>> rounds;
    run_synthetic(floored, image, merged, 100000,
                  [&](const Round& r, const Accumulator&) { rounds.push_back(r.spp); });
    ASSERT_GT(rounds.size(), 2u);
    EXPECT_EQ(rounds[0], std::vector<uint32_t>(4096, 8));
    EXPECT_EQ(rounds[1], std::vector<uint32_t>(4096, 8));
    EXPECT_EQ(merged.total_samples(), 4096u * 32);
    for (size_t i = 0; i < 4096; ++i) ASSERT_GE(merged.samples(i), 16u);
    StrategyParams unfloored = optimal(4096 * 32);
    unfloored.floor_fraction = 0;
    OptimalStrategy plain(unfloored, 64, 64, false);
    Accumulator plain_merged(64, 64);
    run_synthetic(plain, image, plain_merged);
    EXPECT_LT(plain_merged.samples(0), 16u);  // x = 0: the quietest band
    // min_spp stays the floor when the fraction gives less, and max_spp caps both.
    p.min_spp = 20;
    p.max_spp = 18;
    OptimalStrategy capped(p, 64, 64, false);
    Accumulator capped_merged(64, 64);
    run_synthetic(capped, image, capped_merged);
    for (size_t i = 0; i < 4096; ++i) ASSERT_EQ(capped_merged.samples(i), 18u);
}

// Heavy-tailed pixels as in a caustic: each sample is a firefly of 40 with probability
// 1/150, else near 0.1. The seed's E rewards deciding the allocation from many samples
// per pixel here: a pixel whose four pilot samples drew a firefly would otherwise take a
// large share on one lucky sample while its neighbours, equally heavy-tailed, are
// starved.
double heavy_tailed_error(const StrategyParams& p) {
    double total = 0;
    for (uint64_t seed = 1; seed <= 6; ++seed) {
        SyntheticImage image(32, 32, seed, {0.1, 0.02, 1, 1.0 / 150, 40.0});
        OptimalStrategy strategy(p, 32, 32, false);
        Accumulator merged(32, 32);
        run_synthetic(strategy, image, merged);
        total += mean_absolute_error(merged, image);
    }
    return total;
}

TEST(Optimal, AFloorFractionLowersTheErrorOfHeavyTailedPixels) {
    StrategyParams p = optimal(1024 * 64);
    p.steer_rounds = 0;  // the floor as measured, before the steered rounds
    p.plan_ahead = 0;    // and before planning ahead
    p.floor_fraction = 0;
    const double plain = heavy_tailed_error(p);
    p.floor_fraction = 0.5;
    const double floored = heavy_tailed_error(p);
    EXPECT_LT(floored, 0.95 * plain) << floored << " vs " << plain;
}

TEST(Optimal, SteeredRoundsHalveWhatThePilotLeavesAndTheLastSpendsTheRest) {
    // Mean 32 spp on 64x64, floor_fraction 0.5: a 16-spp pilot, then 8 rounds of half
    // of what is left, the 8th all of it; the budget is spent exactly.
    const SyntheticImage image = banded_image();
    StrategyParams p = optimal(4096 * 32);
    // Today's default splits the pilot in two halves; the rest is the same schedule.
    const auto split = [&](std::vector<uint64_t> totals) {
        totals[0] /= 2;
        totals.insert(totals.begin(), totals[0]);
        return totals;
    };
    const auto round_totals = [&](uint32_t steer_rounds) {
        p.steer_rounds = steer_rounds;
        OptimalStrategy strategy(p, 64, 64, false);
        Accumulator merged(64, 64);
        std::vector<uint64_t> totals;
        run_synthetic(
            strategy, image, merged, 100000,
            [&](const Round& r, const Accumulator&) { totals.push_back(r.total()); });
        EXPECT_EQ(merged.total_samples(), 4096u * 32) << steer_rounds;
        return totals;
    };
    EXPECT_EQ(round_totals(8),
              split({65536, 32768, 16384, 8192, 4096, 2048, 1024, 512, 512}));
    EXPECT_EQ(round_totals(1), split({65536, 65536}));
    EXPECT_EQ(round_totals(0), split({65536, 65536}));  // doubling
    p.plan_ahead = 1.0 / 16;                            // the pilot whole
    EXPECT_EQ(round_totals(8), (std::vector<uint64_t>{65536, 32768, 16384, 8192, 4096,
                                                      2048, 1024, 512, 512}));
    // With a 4-spp pilot the rounds first double (a round never spends more than all
    // before it), then halve what is left.
    p.floor_fraction = 0;
    EXPECT_EQ(round_totals(8), (std::vector<uint64_t>{16384, 16384, 32768, 32768, 16384,
                                                      8192, 4096, 2048, 2048}));
}

TEST(Optimal, SteeredRoundsLowerTheErrorOfHeavyTailedPixels) {
    // A firefly drawn in one steered round raises that pixel's sigma, and the next
    // round answers it; with the rest in one round (0), the fireflies of that round
    // stay.
    // (On this image of equal pixels the gain is a few percent; on cornell-caustics,
    // whose fireflies cluster, 6 %: docs/RESULTS.md.)
    StrategyParams p = optimal(1024 * 128);
    p.steer_rounds = 0;
    const double one_round = heavy_tailed_error(p);
    p.steer_rounds = 8;
    const double steered = heavy_tailed_error(p);
    EXPECT_LT(steered, 0.97 * one_round) << steered << " vs " << one_round;
}

TEST(OptimalTime, GivesCheapPixelsMoreSamplesAsSigmaOverCostToTheTwoThirds) {
    // Equal noise; the right half costs 8 rays per sample: n_left / n_right = 8^(2/3)
    // = 4.
    SyntheticImage image(32, 32, 4, {0.5, 0.3});
    for (uint32_t y = 0; y < 32; ++y)
        for (uint32_t x = 16; x < 32; ++x) image.at(x, y).rays = 8;
    const uint64_t budget = 1024 * 64;
    OptimalStrategy strategy(optimal(budget, "optimal-time"), 32, 32, true);
    Accumulator merged(32, 32);
    ASSERT_TRUE(run_synthetic(strategy, image, merged).finished);
    double left = 0, right = 0;
    for (uint32_t y = 0; y < 32; ++y)
        for (uint32_t x = 0; x < 32; ++x)
            (x < 16 ? left : right) += double(merged.samples(y * 32 + x));
    EXPECT_NEAR(left / right, 4.0, 0.2);
    // The budget in rays is the samples' cost at the pilot's mean of 4.5 rays per sample.
    EXPECT_DOUBLE_EQ(strategy.ray_budget(), 4.5 * double(budget));
    EXPECT_LE(double(merged.total_rays()), strategy.ray_budget());
    EXPECT_GT(double(merged.total_rays()), strategy.ray_budget() - 8);
}

TEST(OptimalTime, BeatsOptimalOnExpectedErrorForTheSameRays) {
    SyntheticImage image(32, 32, 4, {0.5, 0.3});
    for (uint32_t y = 0; y < 32; ++y)
        for (uint32_t x = 16; x < 32; ++x) image.at(x, y).rays = 8;
    const uint64_t budget = 1024 * 64;
    OptimalStrategy by_samples(optimal(budget), 32, 32, false);
    OptimalStrategy by_time(optimal(budget, "optimal-time"), 32, 32, true);
    Accumulator a(32, 32), b(32, 32);
    run_synthetic(by_samples, image, a);
    run_synthetic(by_time, image, b);
    EXPECT_NEAR(double(a.total_rays()), double(b.total_rays()),
                0.01 * double(a.total_rays()));
    // Predicted: 0.75 sqrt(6) / sqrt(4.5) = 0.866 of the sample-optimal (here uniform)
    // error.
    EXPECT_NEAR(expected_error(b, image) / expected_error(a, image), 0.866, 0.01);
}

TEST(Optimal, RestoredStateMakesTheSameDecisions) {
    // Saved after the pilot's two halves, where the first steered round has been planned
    // ahead: restored with that round's counts, as a checkpoint holds them, the rest of
    // the render is the same.
    const SyntheticImage image = banded_image();
    for (const bool cost_aware : {false, true}) {
        SCOPED_TRACE(cost_aware ? "optimal-time" : "optimal");
        OptimalStrategy whole(optimal(4096 * 40), 64, 64, cost_aware);
        Accumulator a(64, 64);
        const std::vector<std::vector<uint32_t>> rounds = rounds_of(whole, image, a);
        ASSERT_GT(rounds.size(), 4u);
        OptimalStrategy first(optimal(4096 * 40), 64, 64, cost_aware);
        Accumulator b(64, 64);
        run_synthetic(first, image, b, 2);
        if (std::function<void()> plan = first.take_work_ahead()) plan();
        ASSERT_NE(first.round_planned_ahead(), nullptr);
        OptimalStrategy resumed(optimal(4096 * 40), 64, 64, cost_aware);
        resumed.restore_state(nlohmann::json::parse(first.save_state().dump()));
        resumed.restore_planned_round(*first.round_planned_ahead());
        size_t r = 2;
        run_synthetic(resumed, image, b, 100,
                      [&](const Round& round, const Accumulator&) {
                          ASSERT_LT(r, rounds.size());
                          EXPECT_EQ(round.spp, rounds[r++]);
                      });
        EXPECT_EQ(r, rounds.size());
    }
}

// Which rounds a render of the banded image (32 spp) holds a round planned ahead after.
std::vector<bool> held_after_each_round(const StrategyParams& p) {
    const SyntheticImage image = banded_image();
    OptimalStrategy strategy(p, 64, 64, false);
    Accumulator merged(64, 64);
    std::vector<bool> held;
    run_synthetic(strategy, image, merged, 100000, [&](const Round&, const Accumulator&) {
        held.push_back(strategy.holds_planned_round());
    });
    EXPECT_EQ(merged.total_samples(), 4096u * 32);
    return held;
}

TEST(Optimal, TheRoundAfterASmallSteeredRoundIsPlannedAhead) {
    // Rounds of 65536 (the pilot), 32768, 16384, 8192, 4096, 2048, 1024, 512, 512
    // samples (see above): from the round of 8192, 1/16 of the budget, on, the next is
    // planned while it is out; after the last, that there is none.
    StrategyParams p = optimal(4096 * 32);
    p.plan_ahead = 1.0 / 16;
    EXPECT_EQ(
        held_after_each_round(p),
        (std::vector<bool>{false, false, false, true, true, true, true, true, true}));
    p.plan_ahead = 1.0 / 32;
    EXPECT_EQ(
        held_after_each_round(p),
        (std::vector<bool>{false, false, false, false, true, true, true, true, true}));
    p.plan_ahead = 0;
    EXPECT_EQ(held_after_each_round(p), std::vector<bool>(9, false));
    p.plan_ahead = 1.0 / 4;  // every steered round after the first
    EXPECT_EQ(held_after_each_round(p),
              (std::vector<bool>{false, true, true, true, true, true, true, true, true}));
    // The pilot's share (1/2) too: the pilot in two halves of 8 spp, and every steered
    // round planned ahead, the first from the pilot's first half.
    p.plan_ahead = 1.0 / 2;
    EXPECT_EQ(held_after_each_round(p), std::vector<bool>(10, true));
}

TEST(Optimal, ASplitPilotPlansTheFirstSteeredRoundFromItsFirstHalf) {
    // The pilot's halves are uniform and the render spends its budget as an unsplit one
    // does; the first steered round is the plan of a pilot of 8 spp with 8 more counted
    // as had, so it is not the unsplit render's first steered round.
    const SyntheticImage image = banded_image();
    for (const bool cost_aware : {false, true}) {
        SCOPED_TRACE(cost_aware ? "optimal-time" : "optimal");
        StrategyParams p = optimal(4096 * 32, cost_aware ? "optimal-time" : "optimal");
        p.plan_ahead = 1;
        OptimalStrategy strategy(p, 64, 64, cost_aware);
        Accumulator merged(64, 64);
        const std::vector<std::vector<uint32_t>> rounds =
            rounds_of(strategy, image, merged);
        ASSERT_GE(rounds.size(), 3u);
        EXPECT_EQ(rounds[0], std::vector<uint32_t>(4096, 8));
        EXPECT_EQ(rounds[1], std::vector<uint32_t>(4096, 8));
        EXPECT_NE(*std::min_element(rounds[2].begin(), rounds[2].end()),
                  *std::max_element(rounds[2].begin(), rounds[2].end()));
        if (!cost_aware) {
            EXPECT_EQ(merged.total_samples(), 4096u * 32);
            EXPECT_EQ(rounds.size(), 10u);  // two halves and 8 steered rounds
        } else {
            EXPECT_NEAR(double(merged.total_rays()), strategy.ray_budget(),
                        0.01 * strategy.ray_budget());
        }
        // A render whose pilot is below 4 spp keeps it whole: a half of one sample has no
        // variance.
        StrategyParams small = optimal(4096 * 3, cost_aware ? "optimal-time" : "optimal");
        small.plan_ahead = 1;
        OptimalStrategy whole(small, 64, 64, cost_aware);
        Accumulator m(64, 64);
        const std::optional<Round> first = whole.next_round(m);
        ASSERT_TRUE(first);
        EXPECT_EQ(first->spp, std::vector<uint32_t>(4096, 3));
        EXPECT_FALSE(whole.holds_planned_round());
    }
}

TEST(Optimal, ARoundPlannedAheadIsPlannedWithoutTheRoundOut) {
    // Two renders alike until the round after which the next is planned ahead; then one
    // of them draws a firefly in that round. The round planned ahead is the same for
    // both; the round after it, planned from buffers that hold the firefly, answers it.
    const SyntheticImage image = banded_image();
    StrategyParams p = optimal(4096 * 32);
    p.plan_ahead = 1;
    OptimalStrategy calm(p, 64, 64, false), struck(p, 64, 64, false);
    Accumulator a(64, 64), b(64, 64);
    run_synthetic(calm, image, a, 2);
    run_synthetic(struck, image, b, 2);
    const std::optional<Round> out_a = calm.next_round(a), out_b = struck.next_round(b);
    ASSERT_TRUE(out_a && out_b);
    ASSERT_TRUE(calm.holds_planned_round());
    ASSERT_EQ(out_a->spp, out_b->spp);
    size_t pixel = 0;  // a pixel the round gives samples to
    while (pixel < 4096 && out_a->spp[pixel] == 0) ++pixel;
    ASSERT_LT(pixel, 4096u);
    for (const SampleJob& job : cut_round(*out_a, a)) {
        a.merge(image.trace(job));
        SampleJobResult r = image.trace(job);
        const uint32_t x = uint32_t(pixel % 64), y = uint32_t(pixel / 64);
        const PixelRect& q = job.rect;
        if (x >= q.x && x < q.x + q.width && y >= q.y && y < q.y + q.height) {
            PixelSums& s = r.pixels[(y - job.rect.y) * job.rect.width + x - job.rect.x];
            s.even[0] = s.even[1] = s.even[2] = s.even[0] + 1000;
            s.sum_sq_luminance += 1e6;
        }
        b.merge(r);
    }
    const std::optional<Round> ahead_a = calm.next_round(a),
                               ahead_b = struck.next_round(b);
    ASSERT_TRUE(ahead_a && ahead_b);
    EXPECT_EQ(ahead_a->spp, ahead_b->spp);
    for (const SampleJob& job : cut_round(*ahead_a, a)) a.merge(image.trace(job));
    for (const SampleJob& job : cut_round(*ahead_b, b)) b.merge(image.trace(job));
    const std::optional<Round> after_a = calm.next_round(a),
                               after_b = struck.next_round(b);
    ASSERT_TRUE(after_a && after_b);
    EXPECT_GT(after_b->spp[pixel], after_a->spp[pixel] + 4);
}

TEST(Optimal, ARoundPlannedAheadIsTheSameWhereverItsWorkRuns) {
    // The farm runs the work ahead on another thread while the round out merges; the
    // rounds must be those of a caller that leaves the work to next_round.
    const SyntheticImage image = banded_image();
    for (const bool cost_aware : {false, true}) {
        SCOPED_TRACE(cost_aware ? "optimal-time" : "optimal");
        StrategyParams p = optimal(4096 * 40, cost_aware ? "optimal-time" : "optimal");
        p.plan_ahead = 1;
        OptimalStrategy here(p, 64, 64, cost_aware);
        Accumulator a(64, 64);
        const std::vector<std::vector<uint32_t>> rounds = rounds_of(here, image, a);
        OptimalStrategy elsewhere(p, 64, 64, cost_aware);
        Accumulator b(64, 64);
        size_t r = 0, taken = 0;
        while (const std::optional<Round> round = elsewhere.next_round(b)) {
            std::thread work;
            if (std::function<void()> w = elsewhere.take_work_ahead()) {
                work = std::thread(std::move(w));
                ++taken;
            }
            for (const SampleJob& job : cut_round(*round, b)) b.merge(image.trace(job));
            if (work.joinable()) work.join();
            ASSERT_LT(r, rounds.size());
            EXPECT_EQ(round->spp, rounds[r++]);
        }
        EXPECT_EQ(r, rounds.size());
        EXPECT_GT(taken, 3u);
        EXPECT_EQ(a.total_samples(), b.total_samples());
        EXPECT_EQ(a.total_rays(), b.total_rays());
    }
}

TEST(Optimal, ARestoredRoundPlannedAheadMustBeOneItsStateHoldsAndFitTheImage) {
    const SyntheticImage image = banded_image();
    StrategyParams p = optimal(4096 * 32);
    p.plan_ahead = 1;
    p.max_spp = 1000;
    OptimalStrategy strategy(p, 64, 64, false);
    Accumulator merged(64, 64);
    ASSERT_TRUE(strategy.next_round(merged));  // the pilot's first half; the second held
    const nlohmann::json held = strategy.save_state();
    ASSERT_TRUE(held.contains("ahead"));
    const std::vector<uint32_t> second = *strategy.round_planned_ahead();
    OptimalStrategy fresh(p, 64, 64, false);
    EXPECT_THROW(fresh.restore_planned_round(second), std::runtime_error);  // no state
    fresh.restore_state(held);
    EXPECT_THROW(fresh.restore_planned_round(std::vector<uint32_t>(4095, 8)),
                 std::runtime_error);
    std::vector<uint32_t> above_cap = second;
    above_cap[7] = 1001;
    EXPECT_THROW(fresh.restore_planned_round(above_cap), std::runtime_error);
    // Without its counts the round is never made: an error, not a plan.
    EXPECT_THROW(fresh.next_round(merged), std::logic_error);
    fresh.restore_state(held);
    fresh.restore_planned_round(second);
    const std::optional<Round> round = fresh.next_round(merged);
    ASSERT_TRUE(round);
    EXPECT_EQ(round->spp, second);
    // A method that plans nothing ahead has nothing to restore.
    StrategyParams u;
    u.spp = 4;
    EXPECT_THROW(make_strategy(u, 64, 64)->restore_planned_round(second),
                 std::runtime_error);
    EXPECT_NO_THROW(make_strategy(u, 64, 64)->restore_planned_round({}));
}

TEST(Optimal, ARoundPlannedAheadWhoseWorkWasLostIsAnErrorNotAnotherPlan) {
    // Planning it from the buffers merged since would give other bytes than the render
    // whose plan was made; the session fails the render instead.
    const SyntheticImage image = banded_image();
    StrategyParams p = optimal(4096 * 32);
    p.plan_ahead = 1;
    OptimalStrategy strategy(p, 64, 64, false);
    Accumulator merged(64, 64);
    run_synthetic(strategy, image, merged, 2);
    const std::optional<Round> out = strategy.next_round(merged);
    ASSERT_TRUE(out && strategy.holds_planned_round());
    ASSERT_TRUE(strategy.take_work_ahead());  // taken, and never run
    for (const SampleJob& job : cut_round(*out, merged)) merged.merge(image.trace(job));
    EXPECT_THROW(strategy.next_round(merged), std::logic_error);
}

TEST(OptimalTime, NoRoundFollowsTheOneThatSpendsWhatIsLeft) {
    // Rays per sample vary (Russian roulette), so a round costs less or more than
    // predicted. Here every result comes back a ray short at a third of its pixels:
    // neither a round planned in place nor one planned ahead may add rounds of a few
    // samples for what the last round's prediction missed (in place it added 3, ahead
    // 6). The pilot and 8 steered rounds.
    SyntheticImage image = banded_image();
    for (uint32_t y = 0; y < 64; ++y)
        for (uint32_t x = 0; x < 64; ++x) image.at(x, y).rays = 4;
    for (const double plan_ahead : {0.0, 1.0}) {
        SCOPED_TRACE(plan_ahead);
        StrategyParams p = optimal(4096 * 32, "optimal-time");
        p.plan_ahead = plan_ahead;
        OptimalStrategy strategy(p, 64, 64, true);
        Accumulator merged(64, 64);
        uint32_t rounds = 0;
        while (const std::optional<Round> round = strategy.next_round(merged)) {
            ++rounds;
            for (const SampleJob& job : cut_round(*round, merged)) {
                SampleJobResult r = image.trace(job);
                for (size_t i = 0; i < r.pixels.size(); i += 3)
                    if (r.pixels[i].rays > 0) --r.pixels[i].rays;
                merged.merge(r);
            }
            ASSERT_LT(rounds, 20u);
        }
        EXPECT_EQ(rounds, plan_ahead == 1 ? 10u : 9u);  // at 1, the pilot in two halves
        EXPECT_NEAR(double(merged.total_rays()), strategy.ray_budget(),
                    1e-3 * strategy.ray_budget());
    }
}

TEST(OptimalTime, AWeightIsComputedAgainWhenOnlyItsCostChanged) {
    // A merge that changes a pixel's rays but not its samples leaves its sigma alone:
    // the weight kept from the last round end must not be reused.
    SyntheticImage image(32, 32, 4, {0.5, 0.3});
    OptimalStrategy kept(optimal(1024 * 64), 32, 32, true);
    Accumulator merged(32, 32);
    run_synthetic(kept, image, merged, 2);
    const nlohmann::json before = kept.save_state();
    ASSERT_TRUE(kept.next_round(merged));  // keeps every weight at today's sigma
    kept.restore_state(before);            // as if that round had not been planned
    SampleJobResult rays_only;
    rays_only.rect = {0, 0, 32, 32};
    rays_only.pixels.resize(1024);
    for (size_t i = 0; i < 1024; i += 2) rays_only.pixels[i].rays = 20;
    merged.merge(rays_only);
    OptimalStrategy fresh(optimal(1024 * 64), 32, 32, true);
    fresh.restore_state(before);
    const std::optional<Round> a = kept.next_round(merged), b = fresh.next_round(merged);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->spp, b->spp);
}

}  // namespace
}  // namespace aliquot
