// StrategyParams: which sampling method a render uses and its parameters, with the seed
// report's defaults. One struct for every method so specs store and travel as one thing.
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace aliquot {

class Strategy;

struct StrategyParams {
    std::string method = "uniform";  // one of strategy_methods()

    // uniform: spp, or budget (total samples; spp = floor(budget / pixels)). Adaptive,
    // optimal and optimal-time spend `budget` (or spp * pixels when only spp is given).
    uint64_t spp = 0;
    uint64_t budget = 0;

    // dammertz (seed: max variance V, samples per iteration S, split factor 64)
    double max_variance = 0.0064;
    uint32_t samples_per_iteration = 16;
    double split_factor = 64;
    uint32_t min_bucket_size = 4;  // a bucket side below which it is never split
    std::string error_norm =
        "seed";  // "seed": mean |even - odd|; "paper": Dammertz et al.

    // adaptive (seed: initial samples, max variance, alpha; 16x16 buckets)
    uint32_t initial_spp = 16;
    double alpha = 1.0;
    uint32_t bucket_size = 16;

    // optimal / optimal-time / oracle
    uint32_t min_spp =
        4;  // floor every pixel gets before the allocation trusts its sigma
    // optimal / optimal-time: 0 trusts each pixel's own sample variance (with the
    // protections of optimal_strategy.cpp); r >= 1 pools it, as a plain mean, over the
    // (2r+1)^2 pixels around, so a firefly one pixel drew speaks for its neighbourhood.
    uint32_t sigma_radius = 0;
    // optimal / optimal-time: n0 > 0 shrinks each pixel's variance towards its window's
    // pool (radius max(sigma_radius, 1)) as a prior worth n0 samples: (n s^2 + n0 pool) /
    // (n + n0). Few samples lean on the neighbourhood, many on the pixel itself.
    uint32_t sigma_prior = 0;
    // optimal / optimal-time: r >= 1 takes each pixel's variance from the (2r+1)^2 - 1
    // pixels around it, its own left out, so its own samples no longer set its own count
    // and the image mean loses most of optimal's low bias, for a higher E (docs/
    // RESULTS.md, "Is `optimal` biased low?"). 0: its own, with the protections.
    uint32_t sigma_self_out = 0;
    // optimal / optimal-time: f in [0, 1) raises the pilot and floor to f times the
    // budget's mean spp when that is above min_spp, so the allocation is decided from
    // many samples per pixel whatever the budget (0: min_spp alone). Half by default:
    // heavy-tailed pixels (caustics) need it, smooth noise loses little to it
    // (docs/RESULTS.md, issue 15).
    double floor_fraction = 0.5;
    // optimal / optimal-time: k >= 1 spends what the pilot leaves in k steered rounds,
    // each at most half of what is left (and at most all spent before it), the k-th all
    // of it; sigma is re-estimated from all merged samples before each, so fireflies
    // drawn late are answered (0: rounds that double, what the pilot leaves in one or
    // two rounds at floor_fraction 0.5). 8 by default (docs/RESULTS.md, issue 15).
    uint32_t steer_rounds = 8;
    // optimal / optimal-time: a steered round that spends at most this share of the
    // budget has the round after it planned while it is traced, from the samples merged
    // before it (the round out counted as had), so the farm does not wait for the plan
    // (0: every round planned after the one before has merged). When the pilot's share
    // is at most this too (1/2 at floor_fraction 0.5), the pilot is traced in two halves
    // and the first steered round planned from the first. 1 by default: no round is
    // planned in place, so no round end waits on a plan while each plan is made within
    // the round before (docs/PERFORMANCE.md: to about 16-32 of today's worker cores), for
    // +0.4-0.7 % E on caustics against 1/16, the default before 2026-12-03
    // (docs/STRATEGIES.md, "Planning ahead"; docs/RESULTS.md).
    double plan_ahead = 1;

    // cycles (Blender Cycles' adaptive sampling, with its defaults)
    double noise_threshold = 0.01;
    uint32_t adaptive_min_samples = 0;  // 0: automatic, from the threshold
    uint32_t adaptive_step = 16;        // samples between two convergence checks

    // oracle: the true per-sample standard deviation of each pixel's luminance,
    // row-major, from a separate high-spp render. In-process only: it is not part of the
    // JSON (a coordinator opens no file a client names and takes no image inside
    // parameters), so an oracle render can run only where its caller holds sigma (aliquot
    // render, study).
    std::shared_ptr<const std::vector<float>> true_sigma;

    // Caps that guarantee termination for every method (0: the method's default).
    uint32_t max_spp = 0;
    uint64_t max_samples = 0;
};

// Every parameter of strategy_parameters() and the method. Unknown keys are refused, a
// value out of its bounds too, naming the key and the bounds; missing keys keep their
// defaults (so a spec stored before a parameter existed still reads).
void to_json(nlohmann::json& j, const StrategyParams& p);
void from_json(const nlohmann::json& j, StrategyParams& p);

// Whether `method` needs a sample budget (spp or budget): dammertz and cycles stop by
// their own measure.
bool needs_budget(const std::string& method);
// Samples per pixel a render of a method that needs a budget gets when given neither
// spp nor budget: on the command line and over HTTP alike.
inline constexpr uint64_t kDefaultSpp = 64;

// Throws std::invalid_argument with a message naming the parameter that is wrong
// (unknown method, spp and budget both zero, alpha < 0, ...), including an oracle
// without its sigma.
void validate(const StrategyParams& params, uint32_t width, uint32_t height);
// validate() but for the oracle's sigma: for plans (a study's) that attach sigma only
// when the render is submitted.
void validate_parameters(const StrategyParams& params, uint32_t width, uint32_t height);

std::unique_ptr<Strategy> make_strategy(const StrategyParams& params, uint32_t width,
                                        uint32_t height);

const std::vector<std::string>& strategy_methods();
// The methods a coordinator accepts from a client: what the dashboard offers.
const std::vector<std::string>& submittable_methods();

}  // namespace aliquot
