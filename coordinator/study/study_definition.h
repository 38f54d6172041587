// Study definitions (studies/*.json): groups of renders swept over strategy parameters
// and seeds, plus the tables and charts a report makes of them. Format: docs/STUDIES.md.
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

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
// the samples/s of the same position and seed in group `rate_from` (equal wall time);
// either times `factor`.
struct BudgetSource {
    std::string group;
    std::string match = "samples";
    std::string rate_from;
    // The budget is this many times what matched: uniform at 1.5 times another method's
    // samples asks whether that method saves a third of them (issue 34).
    double factor = 1.0;
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
    // "denoise": every render traces its first hits (albedo, normal) and is measured a
    // second time after Open Image Denoise, against the same reference (issue 34).
    bool denoise = false;
    std::map<std::string, StudyScale> scales;  // small, medium, full (defaults filled in)
    std::vector<StudyGroup> groups;
    nlohmann::json tables = nlohmann::json::array();
    nlohmann::json charts = nlohmann::json::array();
    nlohmann::json conclusions = nlohmann::json::array();
    nlohmann::json source;  // the file as read
    const StudyGroup* group(const std::string& name) const;
};

// Parses and checks a definition; `file` prefixes every message. Throws StudyError.
StudyDefinition parse_study(const std::string& text, const std::string& file);

// The scale called `name` (small, medium, full or one the file defines). Throws
// StudyError.
StudyScale study_scale(const StudyDefinition& def, const std::string& name);

// "seed-report@small".
std::string study_id(const StudyDefinition& def, const StudyScale& scale);

}  // namespace aliquot
