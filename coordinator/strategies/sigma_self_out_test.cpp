// sigma_self_out: optimal's sigma from a pixel's neighbours alone, its own samples left
// out, so that they no longer set its count (docs/RESULTS.md, "Is `optimal` biased
// low?"). The pass against a plain sum, and the option against the bias it is for.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "bands.h"
#include "sigma_passes.h"
#include "strategy_parameters.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace aliquot {
namespace {

// The mean of the window around (x, y) but (x, y), summed pixel by pixel.
double brute_neighbours_mean(const std::vector<double>& v, uint32_t w, uint32_t h,
                             uint32_t r, uint32_t x, uint32_t y) {
    double sum = 0;
    int n = 0;
    for (int yy = int(y) - int(r); yy <= int(y + r); ++yy)
        for (int xx = int(x) - int(r); xx <= int(x + r); ++xx) {
            if (yy < 0 || xx < 0 || yy >= int(h) || xx >= int(w)) continue;
            if (uint32_t(xx) == x && uint32_t(yy) == y) continue;
            sum += v[size_t(yy) * w + xx];
            ++n;
        }
    return n ? sum / n : v[size_t(y) * w + x];
}

TEST(NeighboursMean, IsTheWindowsMeanWithoutThePixelAtEveryEdgeAndSize) {
    std::mt19937_64 rng(7);
    std::exponential_distribution<double> heavy(1.0);
    for (uint32_t r = 1; r <= sigma_passes::kMaxSelfOutRadius; ++r)
        for (auto [w, h] : {std::pair{1u, 1u},
                            {1u, 9u},
                            {9u, 1u},
                            {2u, 3u},
                            {6u, 5u},
                            {7u, 7u},
                            {23u, 17u}}) {
            std::vector<double> v(size_t(w) * h);
            for (double& x : v) x = std::pow(heavy(rng), 4);  // a heavy tail
            std::vector<double> out;
            sigma_passes::neighbours_mean(v, w, h, r, out);
            ASSERT_EQ(out.size(), v.size());
            for (uint32_t y = 0; y < h; ++y)
                for (uint32_t x = 0; x < w; ++x) {
                    const double want = brute_neighbours_mean(v, w, h, r, x, y);
                    EXPECT_NEAR(out[size_t(y) * w + x], want, 1e-12 * want)
                        << w << "x" << h << " r " << r << " at " << x << "," << y;
                }
        }
}

TEST(NeighboursMean, LeavesAFireflysOwnVarianceOutOfItsOwnMean) {
    std::vector<double> v(5 * 5, 0.0);
    v[12] = 1e300;  // the centre: a firefly's variance
    std::vector<double> out;
    sigma_passes::neighbours_mean(v, 5, 5, 1, out);
    EXPECT_EQ(out[12], 0.0);              // not a rounding residue of 1e300
    EXPECT_EQ(out[6], 1e300 / 8);         // its neighbours see it
    EXPECT_EQ(out[0], 0.0);               // beyond the window
    std::vector<double> big(9, 1.7e308);  // sums that overflow: +inf, never NaN
    sigma_passes::neighbours_mean(big, 3, 3, 1, out);
    for (double m : out) EXPECT_FALSE(std::isnan(m));
}

TEST(NeighboursMean, SameBitsWithOneThreadOrMany) {
    const uint32_t w = 300, h = 700;  // several bands of rows
    std::mt19937_64 rng(3);
    std::exponential_distribution<double> heavy(1.0);
    std::vector<double> v(size_t(w) * h);
    for (double& x : v) x = std::pow(heavy(rng), 4);
    const unsigned threads = band_threads();
    std::vector<double> one, many;
    set_band_threads(1);
    sigma_passes::neighbours_mean(v, w, h, 2, one);
    set_band_threads(4);
    sigma_passes::neighbours_mean(v, w, h, 2, many);
    set_band_threads(threads);
    EXPECT_EQ(one, many);
}

// docs/RESULTS.md's synthetic image: every pixel 0.1 +- a uniform of sigma 0.02, or with
// probability 1/150 a firefly of 40, a caustic's heavy tail (true mean 0.366, 73 % of it
// the fireflies'). Every pixel alike, so the true image mean is known exactly.
SyntheticImage heavy_tailed_image(uint64_t seed) {
    return SyntheticImage(64, 64, seed, {0.1, 0.02, 1, 1.0 / 150, 40.0});
}

// The image mean of `p` rendered over `seed`'s image, divided by the true mean, minus 1.
double relative_bias(const StrategyParams& p, uint64_t seed) {
    const SyntheticImage image = heavy_tailed_image(seed);
    const auto strategy = make_strategy(p, image.width(), image.height());
    Accumulator merged(image.width(), image.height());
    EXPECT_TRUE(run_synthetic(*strategy, image, merged).finished);
    const Image img = merged.image();
    double mean = 0, truth = 0;
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        mean += img.rgb[3 * i];
        truth += image.expected(i);
    }
    return mean / truth - 1;
}

struct Bias {
    double mean = 0, standard_error = 0;
};

// Over seeds 1..8: the bias's mean and its standard error from the seeds' spread.
Bias bias_over_seeds(const std::string& method, uint32_t self_out, uint64_t spp) {
    StrategyParams p;
    p.method = method;
    p.spp = spp;
    p.sigma_self_out = self_out;
    constexpr int kSeeds = 8;
    double sum = 0, squares = 0;
    for (int s = 1; s <= kSeeds; ++s) {
        const double b = relative_bias(p, s);
        sum += b;
        squares += b * b;
    }
    const double mean = sum / kSeeds;
    const double variance = (squares - kSeeds * mean * mean) / (kSeeds - 1);
    return {mean, std::sqrt(std::max(variance, 0.0) / kSeeds)};
}

// The option's whole point: today's optimal keeps a pixel that missed the fireflies
// dark (RESULTS: -49 % at 64 spp here); with its own samples out of its count the image
// mean is the truth's within a few standard errors. Fails if the option does nothing.
TEST(SigmaSelfOut, TakesTheLowBiasOutOfAHeavyTailedImagesMean) {
    for (const char* method : {"optimal", "optimal-time"}) {
        const Bias today = bias_over_seeds(method, 0, 64);
        EXPECT_LT(today.mean, -0.3) << method;  // far below the truth
        // r = 1 keeps a little, second order: a firefly raises its neighbours' counts,
        // and their variance its count a round later (RESULTS: -1.3 +- 0.3 % here).
        for (uint32_t r : {1u, 2u}) {
            const Bias out = bias_over_seeds(method, r, 64);
            EXPECT_LT(std::abs(out.mean), 4 * out.standard_error + 0.005)
                << method << " r " << r << ": " << out.mean << " +- "
                << out.standard_error;
        }
    }
}

TEST(SigmaSelfOut, IsAWholeNumberFrom0To3OfOptimalsAlone) {
    const StrategyParameter* p = find_strategy_parameter("sigma_self_out");
    ASSERT_NE(p, nullptr);
    EXPECT_EQ(p->bounds(), "a whole number from 0 to 3");
    EXPECT_EQ(p->flag(), "--sigma-self-out");
    EXPECT_EQ(p->default_value(), 0);
    EXPECT_TRUE(p->applies_to("optimal"));
    EXPECT_TRUE(p->applies_to("optimal-time"));
    EXPECT_FALSE(p->applies_to("denoised"));
    EXPECT_FALSE(p->applies_to("uniform"));
    // What the dashboard's form is made from (GET /api/methods).
    for (const nlohmann::json& m : methods_json()) {
        bool listed = false;
        for (const nlohmann::json& e : m["parameters"])
            if (e["key"] == "sigma_self_out") {
                listed = true;
                EXPECT_EQ(e["default"], 0);
                EXPECT_EQ(e["max"], 3);
            }
        EXPECT_EQ(listed, m["name"] == "optimal" || m["name"] == "optimal-time")
            << m["name"];
    }
    const auto why = [](const nlohmann::json& j) {
        try {
            validate(j.get<StrategyParams>(), 8, 8);
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    EXPECT_EQ(why({{"method", "optimal"}, {"spp", 4}, {"sigma_self_out", 3}}), "");
    EXPECT_NE(why({{"method", "optimal"}, {"spp", 4}, {"sigma_self_out", 4}})
                  .find("'sigma_self_out': expected a whole number from 0 to 3"),
              std::string::npos);
    EXPECT_NE(why({{"method", "optimal"}, {"spp", 4}, {"sigma_self_out", -1}})
                  .find("sigma_self_out"),
              std::string::npos);
    StrategyParams direct;
    direct.method = "optimal-time";
    direct.spp = 4;
    direct.sigma_self_out = 4;  // set in-process, past JSON
    EXPECT_THROW(validate(direct, 8, 8), std::invalid_argument);
    // It replaces the other ways of taking sigma from the neighbourhood.
    for (const char* other : {"sigma_radius", "sigma_prior"}) {
        const nlohmann::json both = {
            {"method", "optimal"}, {"spp", 4}, {"sigma_self_out", 1}, {other, 1}};
        EXPECT_NE(why(both).find("sigma_self_out replaces sigma_radius and sigma_prior"),
                  std::string::npos)
            << other;
    }
}

}  // namespace
}  // namespace aliquot
