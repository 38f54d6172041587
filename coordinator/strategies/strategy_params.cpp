#include "strategy_params.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "adaptive_strategy.h"
#include "allocation.h"
#include "dammertz_strategy.h"
#include "optimal_strategy.h"
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
             {"max_spp", p.max_spp},
             {"max_samples", p.max_samples}};
}

namespace {

void read(const std::string& key, const json& v, std::string& out) {
    if (!v.is_string())
        throw std::invalid_argument("strategy parameter '" + key + "' must be a string");
    out = v.get<std::string>();
}

void read(const std::string& key, const json& v, double& out) {
    if (!v.is_number())
        throw std::invalid_argument("strategy parameter '" + key + "' must be a number");
    out = v.get<double>();
}

template <typename Unsigned>
void read(const std::string& key, const json& v, Unsigned& out) {
    // nlohmann converts -1 or 2.5 to an unsigned silently; a budget must not wrap around.
    constexpr uint64_t top = std::numeric_limits<Unsigned>::max();
    bool ok = false;
    uint64_t value = 0;
    if (v.is_number_unsigned()) {
        value = v.get<uint64_t>();
        ok = value <= top;
    } else if (v.is_number_integer()) {
        ok = v.get<int64_t>() >= 0 && uint64_t(v.get<int64_t>()) <= top;
        value = ok ? uint64_t(v.get<int64_t>()) : 0;
    } else if (v.is_number_float()) {  // 16.0 from a client that only has doubles
        const double d = v.get<double>();
        ok = d >= 0 && d <= double(top) && d == std::floor(d) && d < 0x1p64;
        value = ok ? uint64_t(d) : 0;
    }
    if (!ok)
        throw std::invalid_argument("strategy parameter '" + key +
                                    "' must be a whole number from 0 to " +
                                    std::to_string(top));
    out = Unsigned(value);
}

}  // namespace

void from_json(const json& j, StrategyParams& p) {
    if (!j.is_object())
        throw std::invalid_argument("strategy parameters must be a JSON object");
    for (const auto& [key, v] : j.items()) {
        if (key == "method")
            read(key, v, p.method);
        else if (key == "spp")
            read(key, v, p.spp);
        else if (key == "budget")
            read(key, v, p.budget);
        else if (key == "max_variance")
            read(key, v, p.max_variance);
        else if (key == "samples_per_iteration")
            read(key, v, p.samples_per_iteration);
        else if (key == "split_factor")
            read(key, v, p.split_factor);
        else if (key == "min_bucket_size")
            read(key, v, p.min_bucket_size);
        else if (key == "error_norm")
            read(key, v, p.error_norm);
        else if (key == "initial_spp")
            read(key, v, p.initial_spp);
        else if (key == "alpha")
            read(key, v, p.alpha);
        else if (key == "bucket_size")
            read(key, v, p.bucket_size);
        else if (key == "min_spp")
            read(key, v, p.min_spp);
        else if (key == "max_spp")
            read(key, v, p.max_spp);
        else if (key == "max_samples")
            read(key, v, p.max_samples);
        else
            throw std::invalid_argument("unknown strategy parameter '" + key + "'");
    }
}

const std::vector<std::string>& strategy_methods() {
    static const std::vector<std::string> methods = {"uniform", "dammertz", "adaptive",
                                                     "optimal", "optimal-time"};
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

void validate(const StrategyParams& p, uint32_t width, uint32_t height) {
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
    if (p.method != "dammertz" && p.spp == 0 && p.budget == 0)
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
    if (p.max_spp && p.method.starts_with("optimal") && p.min_spp > p.max_spp)
        fail("min_spp (" + std::to_string(p.min_spp) + ") exceeds max_spp (" +
             std::to_string(p.max_spp) + ")");
    if (p.max_samples > kMaxBudget) fail("max_samples exceeds 2^53 samples");
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
    return std::make_unique<OptimalStrategy>(p, width, height,
                                             p.method == "optimal-time");
}

}  // namespace aliquot
