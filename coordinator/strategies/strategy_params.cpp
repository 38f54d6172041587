#include "strategy_params.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "adaptive_strategy.h"
#include "allocation.h"
#include "cycles_strategy.h"
#include "dammertz_strategy.h"
#include "denoised_strategy.h"
#include "json_field.h"
#include "optimal_strategy.h"
#include "oracle_strategy.h"
#include "strategy_parameters.h"
#include "uniform_strategy.h"

namespace aliquot {

using nlohmann::json;

void to_json(json& j, const StrategyParams& p) {
    j = json{{"method", p.method}};
    for (const StrategyParameter& parameter : strategy_parameters())
        j[parameter.key] = parameter.get(p);
}

void from_json(const json& j, StrategyParams& p) {
    try {
        const JsonField root(j);
        root.expect_object("strategy parameters must be a JSON object");
        if (auto sigma = root.find("sigma"))
            sigma->fail(
                "the oracle's sigma is not a parameter: it is given in-process (aliquot "
                "render --sigma FILE.exr, or a study), never to a coordinator");
        std::vector<std::string> keys = {"method"};
        for (const StrategyParameter& parameter : strategy_parameters())
            keys.push_back(parameter.key);
        root.allow_keys(keys);
        for (const auto& [key, v] : root.members()) {
            if (key == "method")
                p.method = v.string();
            else
                find_strategy_parameter(key)->read(v, p);
        }
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
        "uniform",      "dammertz", "adaptive", "optimal",
        "optimal-time", "oracle",   "cycles",   "denoised"};
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

bool needs_budget(const std::string& method) {
    return method != "dammertz" && method != "cycles";
}

void validate_parameters(const StrategyParams& p, uint32_t width, uint32_t height) {
    const auto& methods = strategy_methods();
    if (std::find(methods.begin(), methods.end(), p.method) == methods.end())
        fail("unknown method '" + p.method + "'; valid methods: " + join(methods));
    if (width == 0 || height == 0)
        fail("image size " + std::to_string(width) + "x" + std::to_string(height) +
             " has no pixels");
    const uint64_t pixels = uint64_t(width) * height;

    // Each parameter's own bounds, from the one table: JSON refuses the same.
    for (const StrategyParameter& parameter : strategy_parameters()) {
        const std::string why = parameter.out_of_bounds(p);
        if (!why.empty()) fail(parameter.key + " " + why);
    }

    // What no parameter's bounds say alone.
    if (p.spp && p.budget) fail("spp and budget are alternatives: give one of them");
    if (p.spp && p.spp > kMaxBudget / pixels)
        fail("spp " + std::to_string(p.spp) + " times " + std::to_string(pixels) +
             " pixels exceeds the largest budget, 2^53 samples");
    if (p.budget / pixels > UINT32_MAX)
        fail("budget " + std::to_string(p.budget) +
             " gives more than 4294967295 samples per pixel");
    if (needs_budget(p.method) && p.spp == 0 && p.budget == 0)
        fail("spp and budget are both 0: method '" + p.method +
             "' needs a sample budget");
    if (p.max_spp && p.method == "adaptive" && p.initial_spp > p.max_spp)
        fail("initial_spp (" + std::to_string(p.initial_spp) + ") exceeds max_spp (" +
             std::to_string(p.max_spp) + ")");
    if (p.max_spp &&
        (p.method.starts_with("optimal") || p.method == "oracle" ||
         p.method == "denoised") &&
        p.min_spp > p.max_spp)
        fail("min_spp (" + std::to_string(p.min_spp) + ") exceeds max_spp (" +
             std::to_string(p.max_spp) + ")");
    if (p.method.starts_with("optimal") && p.sigma_self_out &&
        (p.sigma_radius || p.sigma_prior))
        fail("sigma_self_out replaces sigma_radius and sigma_prior: give one of them");
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
    if (p.method == "denoised") {
        // Its OIDN passes give up when its render ends (Strategy::stop_work).
        auto stop = std::make_shared<std::atomic<bool>>(false);
        return std::make_unique<DenoisedStrategy>(p, width, height,
                                                  oidn_denoise_function(stop), stop);
    }
    return std::make_unique<OptimalStrategy>(p, width, height,
                                             p.method == "optimal-time");
}

}  // namespace aliquot
