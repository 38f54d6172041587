// Where sampling methods fail: degenerate images, budgets and parameters. Every case runs
// every method through make_strategy against a synthetic image and checks that it stops,
// that the image has no NaN, and that the budget is not exceeded.
#include <gtest/gtest.h>

#include <cmath>

#include "dammertz_strategy.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

constexpr uint32_t kMaxRounds = 10000;

StrategyParams params(const std::string& method, uint64_t budget) {
    StrategyParams p;
    p.method = method;
    p.budget = budget;
    // Dammertz caps kept small so that cases it cannot converge stay fast.
    p.samples_per_iteration = 4;
    if (method == "dammertz") p.max_spp = 64;
    return p;
}

struct Outcome {
    std::unique_ptr<Strategy> strategy;
    Accumulator merged;
    SyntheticRun run;
};

// Runs `p` to completion and checks what must hold whatever the input.
Outcome run_checked(StrategyParams p, const SyntheticImage& image) {
    if (p.method == "oracle") {  // the oracle knows the image's true sigma
        auto sigma = std::make_shared<std::vector<float>>(image.pixel_count());
        for (size_t i = 0; i < sigma->size(); ++i) (*sigma)[i] = float(image.sigma(i));
        p.true_sigma = sigma;
    }
    Outcome out{make_strategy(p, image.width(), image.height()),
                Accumulator(image.width(), image.height()),
                {}};
    out.run = run_synthetic(*out.strategy, image, out.merged, kMaxRounds);
    EXPECT_TRUE(out.run.finished)
        << p.method << " did not stop in " << kMaxRounds << " rounds";
    const Image img = out.merged.image(true);
    for (float v : img.rgb)
        EXPECT_TRUE(std::isfinite(v)) << p.method << ": non-finite pixel";
    for (const Image::Channel& c : img.extra)
        for (float v : c.values)
            EXPECT_TRUE(std::isfinite(v)) << p.method << ": non-finite " << c.name;
    if (p.method == "optimal-time") {
        const double rays = out.strategy->outcome().value("ray_budget", 0.0);
        if (rays > 0) {
            EXPECT_LE(double(out.merged.total_rays()), rays) << "ray budget";
        } else {
            EXPECT_LE(out.merged.total_samples(), p.budget);
        }
    } else {
        // planned_samples is the budget, or Dammertz's cap on what it may spend.
        EXPECT_LE(out.merged.total_samples(), out.strategy->planned_samples())
            << p.method;
        if (p.budget) {
            EXPECT_LE(out.merged.total_samples(), p.budget) << p.method;
        }
    }
    return out;
}

SyntheticImage noisy_image(uint32_t w, uint32_t h, uint64_t seed = 3) {
    SyntheticImage image(w, h, seed);
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
            image.at(x, y) = {0.5, 0.05 + 0.5 * double(x) / w, 1 + x % 5};
    return image;
}

TEST(Stability, AllBlackImageStopsWithABlackImage) {
    const SyntheticImage image(32, 32, 1, {0.0, 0.0});
    for (const std::string& method : strategy_methods()) {
        const Outcome o = run_checked(params(method, 32 * 32 * 16), image);
        for (float v : o.merged.image().rgb) ASSERT_EQ(v, 0.0f) << method;
        if (method == "dammertz") {
            EXPECT_EQ(o.strategy->outcome()["stopped_by"], "converged");
        } else {
            EXPECT_EQ(o.merged.total_samples(), 32u * 32 * 16) << method;
        }
    }
}

TEST(Stability, BudgetSmallerThanPixelCountIsSpreadOverTheImage) {
    const SyntheticImage image = noisy_image(40, 30);
    for (const std::string& method : strategy_methods()) {
        const Outcome o = run_checked(params(method, 500), image);
        if (method == "uniform") {
            EXPECT_EQ(o.merged.total_samples(), 0u);  // floor(500 / 1200)
        }
        if (method == "dammertz") {  // the budget caps it; not one sample per pixel fits
            EXPECT_EQ(o.strategy->outcome()["stopped_by"], "max_samples");
        }
        if (method == "adaptive" || method.starts_with("optimal")) {
            EXPECT_EQ(o.merged.total_samples(), 500u) << method;
            uint64_t bottom_half = 0;
            for (size_t i = 0; i < o.merged.pixel_count(); ++i) {
                ASSERT_LE(o.merged.samples(i), 1u);
                if (i >= o.merged.pixel_count() / 2) bottom_half += o.merged.samples(i);
            }
            EXPECT_GT(bottom_half, 150u)
                << method << " gave the samples to the first rows";
        }
    }
}

TEST(Stability, UnreachableVIsStoppedByACapThatTheOutcomeReports) {
    const SyntheticImage image = noisy_image(32, 24);
    StrategyParams p = params("dammertz", 0);
    p.max_variance = 1e-12;
    Outcome o = run_checked(p, image);
    EXPECT_EQ(o.strategy->outcome()["stopped_by"], "max_spp");
    EXPECT_EQ(o.strategy->outcome()["unconverged_pixels"], 32 * 24);
    EXPECT_EQ(o.merged.total_samples(), 64u * 32 * 24);

    p.max_spp = 0;  // the default 65536 per pixel, so the sample cap stops it first
    p.max_samples = 32 * 24 * 50;
    o = run_checked(p, image);
    EXPECT_EQ(o.strategy->outcome()["stopped_by"], "max_samples");
    EXPECT_EQ(o.strategy->outcome()["converged_fraction"], 0.0);
}

TEST(Stability, MaxVarianceAtBothExtremesStopsAndSpendsNoMoreThanTheBudget) {
    const SyntheticImage image = noisy_image(48, 32);
    for (double v : {1e-12, 1e12}) {
        for (const char* method : {"dammertz", "adaptive"}) {
            StrategyParams p = params(method, 48 * 32 * 24);
            p.max_variance = v;
            const Outcome o = run_checked(p, image);
            if (std::string(method) == "adaptive") {
                EXPECT_EQ(o.merged.total_samples(), 48u * 32 * 24);
            }
            if (std::string(method) == "dammertz" && v == 1e12) {
                EXPECT_EQ(o.run.rounds, 1u);  // E <= V at the first look
            }
        }
    }
}

TEST(Stability, AlphaAtBothExtremesSpendsExactlyTheBudget) {
    const SyntheticImage image = noisy_image(48, 32);
    for (double alpha : {0.0, 50.0}) {
        StrategyParams p = params("adaptive", 48 * 32 * 24 + 5);
        p.alpha = alpha;
        p.max_variance =
            1e12;  // with alpha 50, (v / V)^alpha underflows unless kept relative
        const Outcome o = run_checked(p, image);
        EXPECT_EQ(o.merged.total_samples(), 48u * 32 * 24 + 5);
    }
}

TEST(Stability, AFireflyPixelAtLowSppNeitherBreaksNorStarvesTheImage) {
    SyntheticImage image(32, 32, 9, {0.5, 0.1});
    image.at(13, 7) = {0.5, 0.1, 1, 0.002, 5000.0};  // rare and huge: sigma ~ 220
    for (const std::string& method : strategy_methods()) {
        const Outcome o = run_checked(params(method, 32 * 32 * 8), image);
        if (method.starts_with("optimal")) {
            for (size_t i = 0; i < o.merged.pixel_count(); ++i)
                ASSERT_GE(o.merged.samples(i), 4u) << method << ": pixel below min_spp";
        }
    }
}

TEST(Stability, ImageSizesOneByOneAndOddAndVeryWideRunEveryMethod) {
    for (const auto& [w, h] :
         {std::pair{1u, 1u}, std::pair{601u, 377u}, std::pair{4096u, 16u}}) {
        const SyntheticImage image = noisy_image(w, h);
        const uint64_t budget = uint64_t(w) * h * 6 + 1234;
        for (const std::string& method : strategy_methods()) {
            StrategyParams p = params(method, budget);
            if (method == "dammertz") {
                p.samples_per_iteration = 2;
                p.max_spp = 6;
            }
            const Outcome o = run_checked(p, image);
            EXPECT_GT(o.merged.total_samples(), 0u) << method << " " << w << "x" << h;
            if (method == "dammertz") {
                std::vector<int> covered(size_t(w) * h, 0);
                for (const Bucket& b : o.strategy->buckets())
                    for (uint32_t y = b.rect.y; y < b.rect.y + b.rect.height; ++y)
                        for (uint32_t x = b.rect.x; x < b.rect.x + b.rect.width; ++x)
                            ++covered[size_t(y) * w + x];
                for (int c : covered) ASSERT_EQ(c, 1);
            }
        }
    }
}

TEST(Stability, NaNSamplesNeverReachTheImage) {
    SyntheticImage image = noisy_image(32, 32);
    for (uint32_t y = 8; y < 16; ++y)
        for (uint32_t x = 0; x < 32; ++x) image.at(x, y).nan_probability = 0.1;
    image.at(5, 20).nan_probability = 1.0;  // a pixel that only ever returns NaN
    for (const std::string& method : strategy_methods()) {
        const Outcome o = run_checked(params(method, 32 * 32 * 16), image);
        EXPECT_GT(o.merged.total_nonfinite(), 0u) << method;
        double rgb[3];
        o.merged.mean(20 * 32 + 5, rgb);
        EXPECT_EQ(rgb[0], 0.0) << method;  // NaN counted as zero radiance
    }
}

}  // namespace
}  // namespace aliquot
