// Study definitions (studies/*.json): groups of renders swept over strategy parameters
// and seeds, plus the tables and charts a report makes of them. Parsing, scaling and
// expansion into concrete renders; no rendering and no I/O here. Format: docs/STUDIES.md.
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strategy_params.h"

namespace aliquot {

// A malformed study: the message names the file and the JSON pointer of the field, e.g.
// `studies/x.json: /renders/2/method: unknown method "magik"`.
class StudyError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// How a scale shrinks a study: every resolution so that its longer side is at most
// `max_side` (0: unchanged), every per-pixel sample count (spp, initial_spp,
// samples_per_iteration, min_spp, max_spp) by `spp_factor`, Dammertz's V by
// 1/sqrt(spp_factor) (so it is reached at the scaled spp), every absolute budget
// (budget, max_samples) by the pixel ratio times `spp_factor`, and adaptive's bucket_size
// and the error metric's 16-pixel buckets with the resolution, so that a bucket covers
// the same part of the image.
struct StudyScale {
    std::string name = "full";
    uint32_t max_side = 0;
    double spp_factor = 1.0;
    uint64_t reference_spp = 0;  // 0: the study's reference_spp, unscaled
};

// Where a dependent group's budgets come from: the render of group `group` with the same
// sweep position and seed. match "samples": its samples; "seconds": its wall time times
// the samples/s of the same position and seed in group `rate_from` (equal wall time).
struct BudgetSource {
    std::string group;
    std::string match = "samples";
    std::string rate_from;
};

struct StudyGroup {
    std::string name;
    std::string scene;               // built-in name or scene file path
    uint32_t width = 0, height = 0;  // full-scale resolution
    nlohmann::json params;           // StrategyParams keys, method included
    std::string sweep_key;           // empty: one render per seed
    std::vector<nlohmann::json> sweep_values;
    std::vector<uint64_t> seeds;
    std::optional<BudgetSource> budget_from;
};

struct StudyDefinition {
    std::string name, description;
    uint64_t reference_spp = 8192;
    std::map<std::string, StudyScale> scales;  // small, medium, full (defaults filled in)
    std::vector<StudyGroup> groups;
    nlohmann::json tables = nlohmann::json::array();
    nlohmann::json charts = nlohmann::json::array();
    nlohmann::json conclusions = nlohmann::json::array();
    nlohmann::json source;  // the file as read
    const StudyGroup* group(const std::string& name) const;
};

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
};

// Parses and checks a definition; `file` prefixes every message. Throws StudyError.
StudyDefinition parse_study(const std::string& text, const std::string& file);

// The scale called `name` (small, medium, full or one the file defines). Throws
// StudyError.
StudyScale study_scale(const StudyDefinition& def, const std::string& name);

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

// "seed-report@small".
std::string study_id(const StudyDefinition& def, const StudyScale& scale);

}  // namespace aliquot
