// A round end's passes run in bands on the coordinator's threads (bands.h): the rounds a
// strategy plans, the jobs they are cut into and the error estimate must be the same bits
// with one thread as with several.
#include <gtest/gtest.h>

#include "bands.h"
#include "dammertz_strategy.h"
#include "error_estimate.h"
#include "round_cutter.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

// Several bands' worth of pixels (kBandPixels is 65536), with noise, fireflies and ray
// costs that vary across the image and across bands.
SyntheticImage varied_image() {
    SyntheticImage image(640, 256, 3);
    for (uint32_t y = 0; y < image.height(); ++y)
        for (uint32_t x = 0; x < image.width(); ++x) {
            SyntheticPixel& p = image.at(x, y);
            p.mean = 0.1 + 0.8 * double(y) / image.height();
            p.sigma = (x / 32 + y / 32) % 3 == 0 ? 0.6 : 0.02 * (1 + x % 5);
            p.rays = 1 + (x + 2 * y) % 4;
            if ((x * 17 + y * 31) % 101 == 0) {
                p.firefly_probability = 0.05;
                p.firefly_value = 30;
            }
        }
    return image;
}

struct Trace {
    std::vector<std::vector<uint32_t>> rounds;
    std::vector<double> estimates;
    std::vector<SampleJob> jobs;  // the last round's, cut again at the end
};

Trace run_with_threads(const StrategyParams& params, unsigned threads) {
    const unsigned before = band_threads();
    set_band_threads(threads);
    const SyntheticImage image = varied_image();
    const auto strategy = make_strategy(params, image.width(), image.height());
    Accumulator merged(image.width(), image.height());
    Trace trace;
    run_synthetic(*strategy, image, merged, 12,
                  [&](const Round& round, const Accumulator& m) {
                      trace.rounds.push_back(round.spp);
                      trace.estimates.push_back(estimate_mean_abs_error(m));
                  });
    if (!trace.rounds.empty())
        trace.jobs = cut_round(Round{0, trace.rounds.back()}, merged);
    set_band_threads(before);
    return trace;
}

void expect_same_with_one_and_four_threads(const StrategyParams& params) {
    const Trace one = run_with_threads(params, 1), four = run_with_threads(params, 4);
    ASSERT_GE(one.rounds.size(), 1u) << params.method;
    ASSERT_EQ(one.rounds.size(), four.rounds.size()) << params.method;
    for (size_t r = 0; r < one.rounds.size(); ++r) {
        EXPECT_EQ(one.rounds[r], four.rounds[r]) << params.method << " round " << r;
        // Bitwise: the same double, not a close one.
        EXPECT_EQ(std::memcmp(&one.estimates[r], &four.estimates[r], sizeof(double)), 0)
            << params.method << " round " << r << ": " << one.estimates[r] << " vs "
            << four.estimates[r];
    }
    ASSERT_EQ(one.jobs.size(), four.jobs.size()) << params.method;
    for (size_t j = 0; j < one.jobs.size(); ++j) {
        EXPECT_EQ(one.jobs[j].rect, four.jobs[j].rect);
        EXPECT_EQ(one.jobs[j].counts, four.jobs[j].counts);
        EXPECT_EQ(one.jobs[j].first_sample, four.jobs[j].first_sample);
    }
}

StrategyParams method(const std::string& name) {
    StrategyParams p;
    p.method = name;
    p.budget = uint64_t(24) * 640 * 256;
    p.max_variance = 1e-4;
    p.samples_per_iteration = 4;
    p.initial_spp = 4;
    p.max_spp = 256;
    return p;
}

TEST(RoundEndThreads, OptimalPlansTheSameRoundsWithOneThreadOrFour) {
    expect_same_with_one_and_four_threads(method("optimal"));
}

TEST(RoundEndThreads, OptimalTimePlansTheSameRoundsWithOneThreadOrFour) {
    expect_same_with_one_and_four_threads(method("optimal-time"));
}

TEST(RoundEndThreads, PooledAndShrunkSigmaPlanTheSameRoundsWithOneThreadOrFour) {
    StrategyParams pooled = method("optimal");
    pooled.sigma_radius = 2;
    expect_same_with_one_and_four_threads(pooled);
    StrategyParams shrunk = method("optimal-time");
    shrunk.sigma_prior = 8;
    expect_same_with_one_and_four_threads(shrunk);
}

TEST(RoundEndThreads, EveryOtherMethodPlansTheSameRoundsWithOneThreadOrFour) {
    for (const char* name : {"dammertz", "adaptive", "cycles"})
        expect_same_with_one_and_four_threads(method(name));
    StrategyParams uniform = method("uniform");
    uniform.budget *= 3;  // past its first round's 2^22 samples
    expect_same_with_one_and_four_threads(uniform);
}

// Dammertz judges its leaves in bands of leaves, and a large leaf's pixels in bands of
// rows: the tree (each leaf's rectangle, state and E, to the bit) is the same with one,
// two or three threads.
std::vector<DammertzStrategy::Leaf> dammertz_tree_with_threads(unsigned threads) {
    const unsigned before = band_threads();
    set_band_threads(threads);
    const SyntheticImage image = varied_image();
    StrategyParams p = method("dammertz");
    p.max_variance = 0.01;  // leaves split, converge and go on
    p.split_factor = 1000;
    p.budget *= 4;
    p.min_bucket_size = 4;
    DammertzStrategy strategy(p, image.width(), image.height());
    Accumulator merged(image.width(), image.height());
    run_synthetic(strategy, image, merged, 12);
    set_band_threads(before);
    return strategy.leaves();
}

TEST(RoundEndThreads, DammertzGrowsTheSameTreeWithOneTwoOrThreeThreads) {
    const auto one = dammertz_tree_with_threads(1);
    EXPECT_GT(one.size(), 20u);  // the tree was split
    for (unsigned threads : {2u, 3u}) {
        const auto more = dammertz_tree_with_threads(threads);
        ASSERT_EQ(one.size(), more.size()) << threads << " threads";
        for (size_t l = 0; l < one.size(); ++l) {
            EXPECT_EQ(one[l].rect, more[l].rect) << l;
            EXPECT_EQ(one[l].state, more[l].state) << l;
            EXPECT_EQ(std::memcmp(&one[l].error, &more[l].error, sizeof(double)), 0) << l;
        }
    }
}

TEST(RoundEndThreads, BandsCoverEveryItemOnceAtFixedBoundaries) {
    const unsigned before = band_threads();
    set_band_threads(3);
    const size_t items = 1000, band = 64;
    std::vector<int> seen(items, 0);
    std::vector<std::pair<size_t, size_t>> bounds(band_count(items, band));
    for_each_band(items, band, [&](size_t index, size_t begin, size_t end) {
        bounds[index] = {begin, end};
        for (size_t i = begin; i < end; ++i) ++seen[i];
    });
    set_band_threads(before);
    EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), long(items));
    for (size_t b = 0; b < bounds.size(); ++b) {
        EXPECT_EQ(bounds[b].first, b * band);
        EXPECT_EQ(bounds[b].second, std::min(items, (b + 1) * band));
    }
}

TEST(RoundEndThreads, AnExceptionInABandReachesTheCaller) {
    const unsigned before = band_threads();
    set_band_threads(3);
    EXPECT_THROW(for_each_band(100, 10,
                               [](size_t index, size_t, size_t) {
                                   if (index == 7) throw std::runtime_error("band 7");
                               }),
                 std::runtime_error);
    set_band_threads(before);
}

}  // namespace
}  // namespace aliquot
