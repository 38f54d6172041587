#include "strategy_params.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "adaptive_strategy.h"
#include "allocation.h"
#include "cycles_strategy.h"
#include "dammertz_strategy.h"
#include "json_field.h"
#include "optimal_strategy.h"
#include "oracle_strategy.h"
#include "uniform_strategy.h"

namespace aliquot {

using nlohmann::json;

void to_json(json& j, const StrategyParams& p) {
    j = json{{"method", p.method},
             {"spp", p.spp},
             {"budget", p.budget},
             {"max_variance", p.max_variance},
             {"samples_per_iteration", p.samples_per_iteration},
             {"split_factor", p.split_factor},
             {"min_bucket_size", p.min_bucket_size},
             {"error_norm", p.error_norm},
             {"initial_spp", p.initial_spp},
             {"alpha", p.alpha},
             {"bucket_size", p.bucket_size},
             {"min_spp", p.min_spp},
             {"sigma_radius", p.sigma_radius},
             {"sigma_prior", p.sigma_prior},
             {"floor_fraction", p.floor_fraction},
             {"steer_rounds", p.steer_rounds},
             {"plan_ahead", p.plan_ahead},
             {"noise_threshold", p.noise_threshold},
             {"adaptive_min_samples", p.adaptive_min_samples},
             {"adaptive_step", p.adaptive_step},
             {"max_spp", p.max_spp},
             {"max_samples", p.max_samples}};
}

namespace {

template <typename Unsigned>
Unsigned whole(const JsonField& f) {
    return Unsigned(f.whole(0, std::numeric_limits<Unsigned>::max()));
}

void read_member(const std::string& key, const JsonField& v, StrategyParams& p) {
    if (key == "method")
        p.method = v.string();
    else if (key == "spp")
        p.spp = whole<uint64_t>(v);
    else if (key == "budget")
        p.budget = whole<uint64_t>(v);
    else if (key == "max_variance")
        p.max_variance = v.number();
    else if (key == "samples_per_iteration")
        p.samples_per_iteration = whole<uint32_t>(v);
    else if (key == "split_factor")
        p.split_factor = v.number();
    else if (key == "min_bucket_size")
        p.min_bucket_size = whole<uint32_t>(v);
    else if (key == "error_norm")
        p.error_norm = v.string();
    else if (key == "initial_spp")
        p.initial_spp = whole<uint32_t>(v);
    else if (key == "alpha")
        p.alpha = v.number();
    else if (key == "bucket_size")
        p.bucket_size = whole<uint32_t>(v);
    else if (key == "min_spp")
        p.min_spp = whole<uint32_t>(v);
    else if (key == "sigma_radius")
        p.sigma_radius = whole<uint32_t>(v);
    else if (key == "sigma_prior")
        p.sigma_prior = whole<uint32_t>(v);
    else if (key == "floor_fraction")
        p.floor_fraction = v.number();
    else if (key == "steer_rounds")
        p.steer_rounds = whole<uint32_t>(v);
    else if (key == "plan_ahead")
        p.plan_ahead = v.number();
    else if (key == "noise_threshold")
        p.noise_threshold = v.number();
    else if (key == "adaptive_min_samples")
        p.adaptive_min_samples = whole<uint32_t>(v);
    else if (key == "adaptive_step")
        p.adaptive_step = whole<uint32_t>(v);
    else if (key == "max_spp")
        p.max_spp = whole<uint32_t>(v);
    else if (key == "max_samples")
        p.max_samples = whole<uint64_t>(v);
}

}  // namespace

void from_json(const json& j, StrategyParams& p) {
    try {
        const JsonField root(j);
        root.expect_object("strategy parameters must be a JSON object");
        if (auto sigma = root.find("sigma"))
            sigma->fail(
                "the oracle's sigma is not a parameter: it is given in-process (aliquot "
                "render --sigma FILE.exr, or a study), never to a coordinator");
        root.allow_keys({"method",
                         "spp",
                         "budget",
                         "max_variance",
                         "samples_per_iteration",
                         "split_factor",
                         "min_bucket_size",
                         "error_norm",
                         "initial_spp",
                         "alpha",
                         "bucket_size",
                         "min_spp",
                         "sigma_radius",
                         "sigma_prior",
                         "floor_fraction",
                         "steer_rounds",
                         "plan_ahead",
                         "noise_threshold",
                         "adaptive_min_samples",
                         "adaptive_step",
                         "max_spp",
                         "max_samples"});
        for (const auto& [key, v] : root.members()) read_member(key, v, p);
    } catch (const JsonError& e) {
        // Parameters arrive inside other documents (a request, a study): name the
        // parameter, and let the caller say where its parameters sit.
        const std::string& at = e.pointer().value_or("");
        if (at.empty()) throw std::invalid_argument(e.reason());
        throw std::invalid_argument("strategy parameter '" + at.substr(1) +
                                    "': " + e.reason());
    }
}

const std::vector<std::string>& strategy_methods() {
    static const std::vector<std::string> methods = {
        "uniform", "dammertz", "adaptive", "optimal", "optimal-time", "oracle", "cycles"};
    return methods;
}

const std::vector<std::string>& submittable_methods() {
    // All but oracle, whose sigma is given in-process and never over the network.
    static const std::vector<std::string> methods = [] {
        std::vector<std::string> out;
        for (const std::string& m : strategy_methods())
            if (m != "oracle") out.push_back(m);
        return out;
    }();
    return methods;
}

namespace {

[[noreturn]] void fail(const std::string& message) {
    throw std::invalid_argument(message);
}

std::string join(const std::vector<std::string>& words) {
    std::string s;
    for (const std::string& w : words) s += (s.empty() ? "" : ", ") + w;
    return s;
}

// Shares are computed in doubles; beyond 2^53 a budget is no longer exact (and absurd).
constexpr uint64_t kMaxBudget = uint64_t(1) << 53;

}  // namespace

void validate_parameters(const StrategyParams& p, uint32_t width, uint32_t height) {
    const auto& methods = strategy_methods();
    if (std::find(methods.begin(), methods.end(), p.method) == methods.end())
        fail("unknown method '" + p.method + "'; valid methods: " + join(methods));
    if (width == 0 || height == 0)
        fail("image size " + std::to_string(width) + "x" + std::to_string(height) +
             " has no pixels");
    const uint64_t pixels = uint64_t(width) * height;

    if (p.spp && p.budget) fail("spp and budget are alternatives: give one of them");
    if (p.spp > UINT32_MAX) fail("spp " + std::to_string(p.spp) + " exceeds 4294967295");
    if (p.spp && p.spp > kMaxBudget / pixels)
        fail("spp " + std::to_string(p.spp) + " times " + std::to_string(pixels) +
             " pixels exceeds the largest budget, 2^53 samples");
    if (p.budget > kMaxBudget)
        fail("budget " + std::to_string(p.budget) + " exceeds 2^53 samples");
    if (p.budget / pixels > UINT32_MAX)
        fail("budget " + std::to_string(p.budget) +
             " gives more than 4294967295 samples per pixel");
    if (p.method != "dammertz" && p.method != "cycles" && p.spp == 0 && p.budget == 0)
        fail("spp and budget are both 0: method '" + p.method +
             "' needs a sample budget");

    if (std::isnan(p.max_variance) || p.max_variance <= 0)
        fail("max_variance must be greater than 0");
    if (p.samples_per_iteration == 0) fail("samples_per_iteration must be at least 1");
    if (std::isnan(p.split_factor) || p.split_factor < 1)
        fail(
            "split_factor must be at least 1 (a bucket splits when E <= split_factor * "
            "V)");
    if (p.min_bucket_size == 0) fail("min_bucket_size must be at least 1");
    if (p.error_norm != "seed" && p.error_norm != "paper")
        fail("unknown error_norm '" + p.error_norm + "'; valid: seed, paper");
    if (std::isnan(p.alpha) || p.alpha < 0) fail("alpha must be 0 or more");
    if (std::isinf(p.alpha)) fail("alpha must be finite");
    if (p.bucket_size == 0) fail("bucket_size must be at least 1");
    if (p.max_spp && p.method == "adaptive" && p.initial_spp > p.max_spp)
        fail("initial_spp (" + std::to_string(p.initial_spp) + ") exceeds max_spp (" +
             std::to_string(p.max_spp) + ")");
    if (p.max_spp && (p.method.starts_with("optimal") || p.method == "oracle") &&
        p.min_spp > p.max_spp)
        fail("min_spp (" + std::to_string(p.min_spp) + ") exceeds max_spp (" +
             std::to_string(p.max_spp) + ")");
    if (p.max_samples > kMaxBudget) fail("max_samples exceeds 2^53 samples");
    // A radius beyond 64 pools over more than 16641 pixels: not a neighbourhood.
    if (p.sigma_radius > 64) fail("sigma_radius must be at most 64");
    if (p.sigma_prior > (1u << 24)) fail("sigma_prior must be at most 16777216 samples");
    if (!(p.floor_fraction >= 0 && p.floor_fraction < 1))
        fail("floor_fraction must be at least 0 and below 1");
    if (p.steer_rounds > 64) fail("steer_rounds must be at most 64");
    if (!(p.plan_ahead >= 0 && p.plan_ahead <= 1))
        fail("plan_ahead must be at least 0 and at most 1");
    if (!(p.noise_threshold > 0) || std::isinf(p.noise_threshold))
        fail("noise_threshold must be greater than 0 and finite");
    if (p.adaptive_step == 0) fail("adaptive_step must be at least 1");
    if (p.max_spp && p.method == "cycles" && p.adaptive_min_samples > p.max_spp)
        fail("adaptive_min_samples (" + std::to_string(p.adaptive_min_samples) +
             ") exceeds max_spp (" + std::to_string(p.max_spp) + ")");
}

void validate(const StrategyParams& p, uint32_t width, uint32_t height) {
    validate_parameters(p, width, height);
    if (p.method != "oracle") return;
    if (!p.true_sigma)
        fail(
            "method 'oracle' needs the true per-pixel sigma of a separate high-spp "
            "render "
            "(aliquot render --sigma FILE.exr, or a study); it is given in-process only, "
            "so a coordinator refuses oracle renders");
    const uint64_t pixels = uint64_t(width) * height;
    if (p.true_sigma->size() != pixels)
        fail("oracle sigma has " + std::to_string(p.true_sigma->size()) +
             " values for an image of " + std::to_string(pixels) + " pixels");
    for (float s : *p.true_sigma)
        if (!(s >= 0) || std::isinf(s))
            fail("oracle sigma must be finite and not negative at every pixel");
}

std::unique_ptr<Strategy> make_strategy(const StrategyParams& p, uint32_t width,
                                        uint32_t height) {
    validate(p, width, height);
    const size_t pixels = size_t(width) * height;
    if (p.method == "uniform") {
        uint64_t spp = sample_budget(p, pixels) / pixels;  // the seed's floor(B / N)
        if (p.max_spp) spp = std::min<uint64_t>(spp, p.max_spp);
        return std::make_unique<UniformStrategy>(width, height, uint32_t(spp));
    }
    if (p.method == "dammertz")
        return std::make_unique<DammertzStrategy>(p, width, height);
    if (p.method == "adaptive")
        return std::make_unique<AdaptiveStrategy>(p, width, height);
    if (p.method == "oracle") return std::make_unique<OracleStrategy>(p, width, height);
    if (p.method == "cycles") return std::make_unique<CyclesStrategy>(p, width, height);
    return std::make_unique<OptimalStrategy>(p, width, height,
                                             p.method == "optimal-time");
}

}  // namespace aliquot
