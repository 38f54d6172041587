#include "strategy_parameters.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "sigma_passes.h"

namespace aliquot {

using nlohmann::json;

namespace {

using P = StrategyParams;
using Kind = StrategyParameter::Kind;

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Shares are computed in doubles; beyond 2^53 a budget is no longer exact (and absurd).
constexpr double kMaxSamples = 9007199254740992.0;  // 2^53
constexpr double kMaxUint32 = 4294967295.0;

const std::vector<std::string> kOptimal = {"optimal", "optimal-time"};
// optimal's pilot, floor and steered rounds, which `denoised` keeps.
const std::vector<std::string> kSteered = {"optimal", "optimal-time", "denoised"};

StrategyParameter whole(std::string key, StrategyParameter::Member member, double min,
                        double max, std::vector<std::string> methods, std::string help) {
    StrategyParameter p;
    p.key = std::move(key);
    p.member = member;
    p.min = min;
    p.max = max;
    p.methods = std::move(methods);
    p.help = std::move(help);
    return p;
}

StrategyParameter number(std::string key, double P::*member, double min, bool min_open,
                         double max, bool max_open, std::vector<std::string> methods,
                         std::string help) {
    StrategyParameter p =
        whole(std::move(key), member, min, max, std::move(methods), std::move(help));
    p.min_open = min_open;
    p.max_open = max_open;
    return p;
}

std::vector<StrategyParameter> make_table() {
    const std::vector<std::string>& kEveryMethod = strategy_methods();
    std::vector<StrategyParameter> t = {
        // Every method: the sample budget and the caps that guarantee termination.
        whole("spp", &P::spp, 0, kMaxUint32, kEveryMethod,
              "samples per pixel: uniform's count, the others' budget is spp x pixels "
              "(0: none; give spp or budget)"),
        whole("budget", &P::budget, 0, kMaxSamples, kEveryMethod,
              "total samples to spend, instead of spp (0: none)"),
        whole("max_spp", &P::max_spp, 0, kMaxUint32, kEveryMethod,
              "cap on any pixel's samples (0: the method's default)"),
        whole("max_samples", &P::max_samples, 0, kMaxSamples, kEveryMethod,
              "cap on total samples (0: the method's default)"),
        // dammertz (the seed: max variance V, samples per iteration S, split factor)
        whole("samples_per_iteration", &P::samples_per_iteration, 1, kMaxUint32,
              {"dammertz"}, "samples S each active bucket gets per iteration"),
        number("split_factor", &P::split_factor, 1, false, kInfinity, false, {"dammertz"},
               "a bucket splits when its error E <= split_factor x V"),
        whole("min_bucket_size", &P::min_bucket_size, 1, kMaxUint32, {"dammertz"},
              "a bucket side below which a bucket is never split"),
        [] {
            StrategyParameter p;
            p.key = "error_norm";
            p.member = &P::error_norm;
            p.words = {"seed", "paper"};
            p.methods = {"dammertz"};
            p.help =
                "a bucket's error: seed (mean |even - odd|) or paper (Dammertz et al.)";
            return p;
        }(),
        number("max_variance", &P::max_variance, 0, true, kInfinity, false,
               {"dammertz", "adaptive"},
               "dammertz: a bucket is done below this variance V; adaptive: the "
               "variance a bucket's weight is measured against"),
        // adaptive (the seed: initial samples, max variance, alpha; square buckets)
        whole("initial_spp", &P::initial_spp, 0, kMaxUint32, {"adaptive"},
              "samples every pixel gets in the uniform first pass"),
        number("alpha", &P::alpha, 0, false, kInfinity, false, {"adaptive"},
               "exponent of the buckets' variance ratio in their share of the budget"),
        whole("bucket_size", &P::bucket_size, 1, kMaxUint32, {"adaptive"},
              "side of the square buckets samples are shared among"),
        // optimal, optimal-time and oracle
        whole("min_spp", &P::min_spp, 0, kMaxUint32,
              {"optimal", "optimal-time", "oracle", "denoised"},
              "samples every pixel gets before the allocation trusts its sigma"),
        whole("sigma_radius", &P::sigma_radius, 0, 64, kOptimal,
              "pool each pixel's variance over the (2r+1)^2 pixels around it (0: its "
              "own)"),
        whole("sigma_prior", &P::sigma_prior, 0, 16777216, kOptimal,
              "shrink each pixel's variance towards its neighbourhood's, a prior worth "
              "this many samples (0: off)"),
        whole("sigma_self_out", &P::sigma_self_out, 0, sigma_passes::kMaxSelfOutRadius,
              kOptimal,
              "take each pixel's variance from the (2r+1)^2 - 1 pixels around it, its "
              "own left out: the image mean unbiased but for a little, E higher (0: "
              "its own)"),
        number("floor_fraction", &P::floor_fraction, 0, false, 1, true, kSteered,
               "pilot and floor at this share of the budget's mean spp (0: min_spp "
               "alone)"),
        whole("steer_rounds", &P::steer_rounds, 0, 64, kSteered,
              "spend what the pilot leaves in this many rounds, each at most half of "
              "what is left (0: rounds that double)"),
        number("plan_ahead", &P::plan_ahead, 0, false, 1, false, kOptimal,
               "plan the round after a steered round of at most this share of the "
               "budget while that round is traced; at least the pilot's share: the "
               "pilot in two halves, no round planned in place (0: never)"),
        // cycles (Blender Cycles' adaptive sampling, with its defaults)
        number("noise_threshold", &P::noise_threshold, 0, true, kInfinity, false,
               {"cycles"}, "a pixel stops when its estimated noise is below this"),
        whole("adaptive_min_samples", &P::adaptive_min_samples, 0, kMaxUint32, {"cycles"},
              "samples before the first convergence check (0: automatic)"),
        whole("adaptive_step", &P::adaptive_step, 1, kMaxUint32, {"cycles"},
              "samples between two convergence checks"),
    };
    return t;
}

// 0.5 and 1e-05 as JSON writes them, but whole numbers without a ".0".
std::string number_text(double v) {
    if (v == std::floor(v) && std::abs(v) < 1e15) return std::to_string(int64_t(v));
    return json(v).dump();
}

std::string whole_text(double v) { return std::to_string(uint64_t(v)); }

}  // namespace

Kind StrategyParameter::kind() const {
    if (std::holds_alternative<std::string P::*>(member)) return Kind::Word;
    if (std::holds_alternative<double P::*>(member)) return Kind::Number;
    return Kind::Whole;
}

bool StrategyParameter::applies_to(std::string_view method) const {
    return std::find(methods.begin(), methods.end(), method) != methods.end();
}

std::string StrategyParameter::flag() const {
    std::string f = "--" + key;
    std::replace(f.begin(), f.end(), '_', '-');
    return f;
}

std::string StrategyParameter::bounds() const {
    switch (kind()) {
        case Kind::Word: {
            std::string s;
            for (size_t i = 0; i < words.size(); ++i)
                s += (i == 0 ? "" : i + 1 == words.size() ? " or " : ", ") + words[i];
            return s;
        }
        case Kind::Whole:
            return "a whole number from " + whole_text(min) + " to " + whole_text(max);
        case Kind::Number:
            break;
    }
    const std::string low = (min_open ? "greater than " : "at least ") + number_text(min);
    if (std::isinf(max)) return "a number " + low;
    if (!min_open && !max_open)
        return "a number from " + number_text(min) + " to " + number_text(max);
    return "a number " + low + " and " + (max_open ? "below " : "at most ") +
           number_text(max);
}

json StrategyParameter::get(const StrategyParams& p) const {
    return std::visit([&](auto m) { return json(p.*m); }, member);
}

void StrategyParameter::read(const JsonField& v, StrategyParams& p) const {
    std::visit(
        [&](auto m) {
            using T = std::remove_cvref_t<decltype(p.*m)>;
            if constexpr (std::is_same_v<T, std::string>) {
                const std::string word = v.string("expected " + bounds());
                if (std::find(words.begin(), words.end(), word) == words.end())
                    v.fail("expected " + bounds() + ", got \"" + word.substr(0, 64) +
                           "\"");
                p.*m = word;
            } else if constexpr (std::is_same_v<T, double>) {
                const double d = v.number("expected " + bounds());
                p.*m = d;
                if (!out_of_bounds(p).empty())
                    v.fail("expected " + bounds() + ", got " + number_text(d));
            } else {
                p.*m = T(v.whole(uint64_t(min), uint64_t(max)));
            }
        },
        member);
}

std::string StrategyParameter::out_of_bounds(const StrategyParams& p) const {
    return std::visit(
        [&](auto m) -> std::string {
            using T = std::remove_cvref_t<decltype(p.*m)>;
            const T& value = p.*m;
            if constexpr (std::is_same_v<T, std::string>) {
                if (std::find(words.begin(), words.end(), value) != words.end())
                    return "";
                return "must be " + bounds() + ", got \"" + value + "\"";
            } else if constexpr (std::is_same_v<T, double>) {
                // NaN fails both comparisons, and a Number is finite whatever its max.
                const bool ok = (min_open ? value > min : value >= min) &&
                                (max_open ? value < max : value <= max) &&
                                std::isfinite(value);
                if (ok) return "";
                return "must be " + bounds() + ", got " +
                       (std::isfinite(value) ? number_text(value)
                                             : std::to_string(value));
            } else {
                // As integers: 2^53 + 1 is no double.
                if (uint64_t(value) >= uint64_t(min) && uint64_t(value) <= uint64_t(max))
                    return "";
                return "must be " + bounds() + ", got " + std::to_string(value);
            }
        },
        member);
}

const std::vector<StrategyParameter>& strategy_parameters() {
    static const std::vector<StrategyParameter> table = make_table();
    return table;
}

const StrategyParameter* find_strategy_parameter(std::string_view key) {
    for (const StrategyParameter& p : strategy_parameters())
        if (p.key == key) return &p;
    return nullptr;
}

const std::string& method_summary(const std::string& method) {
    static const std::map<std::string, std::string> summaries = {
        {"uniform", "the same samples at every pixel"},
        {"dammertz",
         "Dammertz et al.'s hierarchical buckets: sample where the error is, split "
         "buckets that are done; stops at its own measure, no budget needed"},
        {"adaptive",
         "a uniform pass, then the budget shared among square buckets by their "
         "variance"},
        {"optimal",
         "a pilot, then each pixel's samples in proportion to its noise, steered "
         "over several rounds"},
        {"optimal-time",
         "optimal, weighing each pixel's noise by what its samples cost in time"},
        {"oracle",
         "optimal steered by the true sigma of a separate render (in-process only: "
         "aliquot render --sigma, or a study)"},
        {"denoised",
         "optimal's pilot and rounds, each pixel's samples in proportion to the noise "
         "left after denoising (Open Image Denoise), measured from the two denoised "
         "half images"},
        {"cycles",
         "Blender Cycles' adaptive sampling: pixels stop when their noise is below a "
         "threshold; no budget needed"},
    };
    static const std::string none;
    const auto it = summaries.find(method);
    return it == summaries.end() ? none : it->second;
}

json methods_json() {
    const auto& submittable = submittable_methods();
    json methods = json::array();
    for (const std::string& name : strategy_methods()) {
        json parameters = json::array();
        for (const StrategyParameter& p : strategy_parameters()) {
            if (!p.applies_to(name)) continue;
            // spp's default is what a render given neither spp nor budget gets.
            const bool default_spp = p.key == "spp" && needs_budget(name);
            json entry = {
                {"key", p.key},
                {"default", default_spp ? json(kDefaultSpp) : p.default_value()},
                {"bounds", p.bounds()},
                {"help", p.help}};
            switch (p.kind()) {
                case Kind::Word:
                    entry["kind"] = "word";
                    entry["values"] = p.words;
                    break;
                case Kind::Whole:
                    entry["kind"] = "whole";
                    entry["min"] = uint64_t(p.min);
                    entry["max"] = uint64_t(p.max);
                    break;
                case Kind::Number:
                    entry["kind"] = "number";
                    entry["min"] = p.min;
                    if (!std::isinf(p.max)) entry["max"] = p.max;
                    if (p.min_open) entry["min_exclusive"] = true;
                    if (p.max_open) entry["max_exclusive"] = true;
                    break;
            }
            parameters.push_back(std::move(entry));
        }
        const bool can_submit =
            std::find(submittable.begin(), submittable.end(), name) != submittable.end();
        methods.push_back({{"name", name},
                           {"summary", method_summary(name)},
                           {"submittable", can_submit},
                           {"parameters", std::move(parameters)}});
    }
    return methods;
}

}  // namespace aliquot
