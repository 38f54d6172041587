// The plan of a study at a scale: every concrete render, scaled, in an order where each
// comes after the renders its budget depends on. No rendering and no I/O here.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "strategy_params.h"
#include "study_definition.h"

namespace aliquot {

// One concrete render of a study at a scale.
struct StudyRender {
    std::string key;  // "group/index/seed": stable across runs, the unit of resumption
    std::string group;
    size_t index = 0;  // position in the sweep (or in the budget source's renders)
    nlohmann::json sweep_value;  // null without a sweep
    std::string scene;
    uint32_t width = 0, height = 0;
    uint64_t seed = 0;
    StrategyParams strategy;
    // Set for a render whose budget comes from other renders; resolve_budget fills it in.
    std::optional<BudgetSource> budget_from;
    std::string source_key, rate_key;  // the renders it depends on
    bool save_maps = false;            // a maps chart shows it: keep per-pixel maps
    uint32_t metric_bucket = 16;  // side of the buckets of the bucket errors, scaled too
    bool denoise = false;  // traced with its first hits, measured after denoising too
};

// Every render of the study at `scale`, in an order where each render comes after the
// renders its budget depends on. Dependent renders carry budget_from and are not runnable
// until resolve_budget. Throws StudyError when a scaled parameter becomes invalid.
std::vector<StudyRender> expand_study(const StudyDefinition& def,
                                      const StudyScale& scale);

// Fills in a dependent render's budget from its source's samples (match "samples") or its
// source's seconds times the rate render's samples/s (match "seconds"). At least 1 sample
// per pixel.
void resolve_budget(StudyRender& render, uint64_t source_samples, double source_seconds,
                    double rate_samples_per_second);

// The identity of a render's output: scene, size, seed and strategy, as canonical JSON.
// A finished render whose spec equals the current one is not rendered again.
std::string render_spec_json(const StudyRender& render);

}  // namespace aliquot
