#include "denoised_strategy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <thread>

#include "round_cutter.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

// A deterministic stand-in for OIDN: the mean of the (2r+1)^2 window around each pixel,
// clipped at the edges, over the columns [from, to) only; the other columns pass
// through as they are.
DenoiseFunction box_smoother(uint32_t r, uint32_t from = 0, uint32_t to = UINT32_MAX) {
    return [=](const Image& in, const Image*, const Image*) {
        Image out = in;
        const uint32_t w = in.width, h = in.height;
        for (uint32_t y = 0; y < h; ++y)
            for (uint32_t x = std::min(from, w); x < std::min(to, w); ++x) {
                double sum[3] = {0, 0, 0};
                int count = 0;
                for (uint32_t yy = y > r ? y - r : 0; yy < std::min(h, y + r + 1); ++yy)
                    for (uint32_t xx = x > r ? x - r : 0; xx < std::min(w, x + r + 1);
                         ++xx, ++count)
                        for (int c = 0; c < 3; ++c)
                            sum[c] += in.rgb[3 * (size_t(yy) * w + xx) + c];
                for (int c = 0; c < 3; ++c)
                    out.rgb[3 * (size_t(y) * w + x) + c] = float(sum[c] / count);
            }
        return out;
    };
}

DenoiseFunction identity() {
    return [](const Image& in, const Image*, const Image*) { return in; };
}

StrategyParams budgeted(const std::string& method, uint64_t spp) {
    StrategyParams p;
    p.method = method;
    p.spp = spp;
    return p;
}

// E of the denoised render against what the image converges to (the denoiser's bias
// included: it is the same for every method run through it).
double denoised_error(const Accumulator& merged, const SyntheticImage& image,
                      const DenoiseFunction& denoise) {
    Image raw(merged.width(), merged.height());
    for (size_t i = 0; i < merged.pixel_count(); ++i) {
        double rgb[3];
        merged.mean(i, rgb);
        for (int c = 0; c < 3; ++c) raw.rgb[3 * i + c] = float(rgb[c]);
    }
    const Image out = denoise(raw, nullptr, nullptr);
    double sum = 0;
    for (size_t i = 0; i < merged.pixel_count(); ++i)
        for (int c = 0; c < 3; ++c)
            sum += std::abs(out.rgb[3 * i + c] - image.expected(i));
    return sum / double(3 * merged.pixel_count());
}

double run_denoised_error(Strategy& strategy, const SyntheticImage& image,
                          const DenoiseFunction& denoise, Accumulator& merged) {
    EXPECT_TRUE(run_synthetic(strategy, image, merged).finished);
    return denoised_error(merged, image, denoise);
}

double mean_samples(const Accumulator& merged, uint32_t from, uint32_t to) {
    double sum = 0, n = 0;
    for (uint32_t y = 0; y < merged.height(); ++y)
        for (uint32_t x = from; x < to; ++x, ++n)
            sum += merged.samples(y * merged.width() + x);
    return sum / n;
}

TEST(Denoised, WithNoDenoiserTheHalvesMeasureTheRawSigma) {
    // An identity denoiser leaves (even - odd)^2 / 4 = the full mean's variance, so n
    // times it is one sample's variance: the raw sigma^2, here 0.09 everywhere (unpooled,
    // radius 0, so the mean over pixels is that of the variance itself).
    SyntheticImage image(16, 16, 3, {0.5, 0.3});
    StrategyParams p = budgeted("uniform", 256);
    const auto uniform = make_strategy(p, 16, 16);
    Accumulator merged(16, 16);
    run_synthetic(*uniform, image, merged);
    const std::vector<double> sigma =
        DenoisedStrategy::denoised_sigma(merged, nullptr, identity(), 0);
    double variance = 0;
    for (double s : sigma) variance += s * s / double(sigma.size());
    EXPECT_NEAR(variance, 0.09, 0.015);
}

TEST(Denoised, OneVeryNoisyPixelDoesNotSpeakForItsNeighbours) {
    // Pooled by the window's median, a pixel as noisy as a light's edge (sigma 50 among
    // 0.1) leaves its neighbours their own estimates (a mean would give each of the 24
    // around it a 25th of its variance, sigma ~10); it is taken at its window's median
    // too: one pixel alone does not steer the rounds.
    SyntheticImage image(16, 16, 5, {0.5, 0.1});
    image.at(8, 8).sigma = 50;
    const auto uniform = make_strategy(budgeted("uniform", 64), 16, 16);
    Accumulator merged(16, 16);
    run_synthetic(*uniform, image, merged);
    const std::vector<double> sigma =
        DenoisedStrategy::denoised_sigma(merged, nullptr, identity(), 2);
    for (uint32_t y = 6; y <= 10; ++y)
        for (uint32_t x = 6; x <= 10; ++x)
            EXPECT_LT(sigma[y * 16 + x], 0.3) << x << "," << y;
}

TEST(Denoised, SpendsWhereTheDenoiserLeavesTheNoise) {
    // The same noise everywhere, but the denoiser smooths the left half only: optimal
    // would sample evenly, denoised spends on the right, where the noise stays, and its
    // denoised image is closer to the truth than uniform's at the same budget. A floor of
    // a quarter of the mean spp leaves the allocation room to show it.
    const uint32_t w = 96, h = 48;
    SyntheticImage image(w, h, 11, {0.5, 0.4});
    const DenoiseFunction denoise = box_smoother(3, 0, w / 2);
    StrategyParams p = budgeted("denoised", 48);
    p.floor_fraction = 0.25;
    DenoisedStrategy denoised(p, w, h, denoise);
    Accumulator with_denoised(w, h);
    const double e_denoised = run_denoised_error(denoised, image, denoise, with_denoised);
    EXPECT_EQ(with_denoised.total_samples(), uint64_t(48) * w * h);
    const double left = mean_samples(with_denoised, 0, w / 2 - 3);
    const double right = mean_samples(with_denoised, w / 2 + 3, w);
    EXPECT_GT(right, 2 * left) << left << " " << right;

    const auto uniform = make_strategy(budgeted("uniform", 48), w, h);
    Accumulator with_uniform(w, h);
    const double e_uniform = run_denoised_error(*uniform, image, denoise, with_uniform);
    EXPECT_LT(e_denoised, 0.95 * e_uniform);
}

TEST(Denoised, BeatsUniformAfterTheDenoiserWhereTheNoiseDiffers) {
    // A noisy left half and a nearly clean right half under a smoother over the whole
    // image: uniform wastes the right half's samples.
    const uint32_t w = 64, h = 64;
    SyntheticImage image(w, h, 5, {0.5, 0.02});
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w / 2; ++x) image.at(x, y).sigma = 1.0;
    const DenoiseFunction denoise = box_smoother(2);
    DenoisedStrategy denoised(budgeted("denoised", 64), w, h, denoise);
    Accumulator a(w, h), b(w, h);
    const double e_denoised = run_denoised_error(denoised, image, denoise, a);
    const auto uniform = make_strategy(budgeted("uniform", 64), w, h);
    const double e_uniform = run_denoised_error(*uniform, image, denoise, b);
    EXPECT_LT(e_denoised, 0.92 * e_uniform);
}

TEST(Denoised, IsDeterministic) {
    SyntheticImage image(24, 16, 9, {0.5, 0.4});
    for (uint32_t y = 0; y < 16; ++y) image.at(3, y).firefly_probability = 0.01;
    for (uint32_t y = 0; y < 16; ++y) image.at(3, y).firefly_value = 50;
    std::vector<std::vector<uint32_t>> rounds[2];
    for (int run = 0; run < 2; ++run) {
        DenoisedStrategy s(budgeted("denoised", 48), 24, 16, box_smoother(1));
        Accumulator merged(24, 16);
        run_synthetic(s, image, merged, 1000, [&](const Round& r, const Accumulator&) {
            rounds[run].push_back(r.spp);
        });
    }
    EXPECT_GT(rounds[0].size(), 2u);
    EXPECT_EQ(rounds[0], rounds[1]);
}

// Issue 33's review: a round end's two denoiser passes ran under the render's lock. Now
// take_round_end copies what the plan reads and the plan runs elsewhere (RenderSession:
// a thread of its own); the rounds are those planned in place, whether the work ran on
// another thread, or was taken and never run (next_round then plans from the copy).
TEST(Denoised, ARoundEndPlannedOffTheLockIsTheRoundPlannedInPlace) {
    SyntheticImage image(24, 16, 9, {0.5, 0.4});
    for (uint32_t y = 0; y < 16; ++y) image.at(3, y).firefly_probability = 0.01;
    for (uint32_t y = 0; y < 16; ++y) image.at(3, y).firefly_value = 50;
    std::vector<std::vector<uint32_t>> in_place;
    {
        DenoisedStrategy s(budgeted("denoised", 48), 24, 16, box_smoother(1));
        Accumulator merged(24, 16);
        run_synthetic(s, image, merged, 1000, [&](const Round& r, const Accumulator&) {
            in_place.push_back(r.spp);
        });
    }
    ASSERT_GT(in_place.size(), 2u);
    for (const bool run_work : {true, false}) {
        DenoisedStrategy s(budgeted("denoised", 48), 24, 16, box_smoother(1));
        Accumulator merged(24, 16);
        std::vector<std::vector<uint32_t>> off_lock;
        size_t works = 0;
        while (true) {
            if (std::function<void()> work = s.take_round_end(merged)) {
                ++works;
                if (run_work) std::thread(work).join();
            }
            const std::optional<Round> round = s.next_round(merged);
            if (!round) break;
            for (const SampleJob& job : cut_round(*round, merged))
                merged.merge(image.trace(job));
            off_lock.push_back(round->spp);
        }
        EXPECT_EQ(off_lock, in_place) << (run_work ? "work run" : "work not run");
        // Every steered round, none for the pilot nor after the budget is spent.
        EXPECT_EQ(works, in_place.size() - 1);
    }
}

TEST(Denoised, ContinuesFromItsSavedStateAsItWouldHave) {
    SyntheticImage image(16, 16, 4, {0.5, 0.4});
    for (uint32_t y = 0; y < 16; ++y) image.at(2, y).sigma = 2;
    DenoisedStrategy whole(budgeted("denoised", 32), 16, 16, box_smoother(1));
    Accumulator a(16, 16);
    std::vector<std::vector<uint32_t>> expected;
    run_synthetic(whole, image, a, 1000,
                  [&](const Round& r, const Accumulator&) { expected.push_back(r.spp); });

    DenoisedStrategy first(budgeted("denoised", 32), 16, 16, box_smoother(1));
    Accumulator b(16, 16);
    std::vector<std::vector<uint32_t>> got;
    run_synthetic(first, image, b, 2,
                  [&](const Round& r, const Accumulator&) { got.push_back(r.spp); });
    DenoisedStrategy second(budgeted("denoised", 32), 16, 16, box_smoother(1));
    second.restore_state(first.save_state());
    run_synthetic(second, image, b, 1000,
                  [&](const Round& r, const Accumulator&) { got.push_back(r.spp); });
    EXPECT_EQ(got, expected);
}

TEST(Denoised, AsksForTheFirstHitsAndIsRefusedWithoutOpenImageDenoise) {
    DenoisedStrategy s(budgeted("denoised", 8), 4, 4, identity());
    EXPECT_TRUE(s.wants_first_hits());
    // No library where the variable points: the render is refused at once, saying why.
    setenv("ALIQUOT_OIDN_LIBRARY", "/nonexistent/libOpenImageDenoise.so.2", 1);
    try {
        make_strategy(budgeted("denoised", 8), 4, 4);
        ADD_FAILURE() << "made a denoised strategy without OIDN";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("Open Image Denoise"), std::string::npos)
            << e.what();
    }
    unsetenv("ALIQUOT_OIDN_LIBRARY");
}

}  // namespace
}  // namespace aliquot
