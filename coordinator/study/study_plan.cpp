#include "study_plan.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace aliquot {

using nlohmann::json;

namespace {

// Keys of StrategyParams that count samples per pixel, and those that count samples.
const std::set<std::string> kPerPixelKeys = {
    "spp", "initial_spp", "samples_per_iteration", "min_spp", "max_spp"};
const std::set<std::string> kTotalKeys = {"budget", "max_samples"};
// Adaptive's bucket side: its variance is a statistic of an area of the image, so the
// side shrinks with the resolution. Dammertz's min_bucket_size is not scaled: it bounds
// how finely the tree splits, and 1-pixel buckets (each its own job every round) made a
// 64x64 run some 20 times slower per sample.
const std::set<std::string> kSideKeys = {"bucket_size"};
// Defaults a method uses that a scale changes, filled in before scaling. Only the
// method's own: a uniform render's spec then does not change with Dammertz's bucket size.
const std::map<std::string, std::vector<std::string>> kScaledDefaults = {
    {"dammertz", {"samples_per_iteration"}},
    {"adaptive", {"initial_spp", "bucket_size"}},
    {"optimal", {"min_spp"}},
    {"optimal-time", {"min_spp"}},
};

std::string in_quotes(const std::string& s) { return "\"" + s + "\""; }

uint64_t scale_count(uint64_t v, double factor, uint64_t floor) {
    if (v == 0) return 0;
    return std::max<uint64_t>(floor, uint64_t(std::llround(double(v) * factor)));
}

// A group's size at a scale, and how much smaller it is than at full scale.
struct ScaledSize {
    uint32_t width = 0, height = 0;
    uint64_t pixels = 0;
    double pixel_ratio = 1, side_ratio = 1;
};

ScaledSize scaled_size(const StudyGroup& g, const StudyScale& scale) {
    ScaledSize s{g.width, g.height};
    if (scale.max_side && std::max(s.width, s.height) > scale.max_side) {
        const double f = double(scale.max_side) / std::max(s.width, s.height);
        s.width = std::max<uint32_t>(1, uint32_t(std::lround(s.width * f)));
        s.height = std::max<uint32_t>(1, uint32_t(std::lround(s.height * f)));
    }
    s.pixels = uint64_t(s.width) * s.height;
    s.pixel_ratio = double(s.pixels) / (double(g.width) * g.height);
    s.side_ratio = double(std::max(s.width, s.height)) / std::max(g.width, g.height);
    return s;
}

json scaled_params(json p, const ScaledSize& size, const StudyScale& scale) {
    const json defaults = StrategyParams{};
    if (const auto it = kScaledDefaults.find(p.value("method", ""));
        it != kScaledDefaults.end())
        for (const std::string& k : it->second)
            if (!p.contains(k)) p[k] = defaults[k];
    for (auto& [k, v] : p.items()) {
        if (!v.is_number()) continue;
        if (kSideKeys.count(k))
            v = std::max<uint64_t>(
                1, uint64_t(std::llround(v.get<double>() * size.side_ratio)));
        else if (kPerPixelKeys.count(k))
            v = scale_count(v.get<uint64_t>(), scale.spp_factor, 1);
        else if (kTotalKeys.count(k))
            v = scale_count(v.get<uint64_t>(), size.pixel_ratio * scale.spp_factor,
                            size.pixels);
        else if (k == "max_variance" && p.value("method", "") == "dammertz")
            v = v.get<double>() / std::sqrt(scale.spp_factor);
    }
    return p;
}

// Expands one group at a time; `by_group` remembers where each group's renders went, for
// the groups whose budgets come from them.
class PlanBuilder {
public:
    PlanBuilder(const StudyDefinition& def, const StudyScale& scale)
        : scale_(scale), mapped_(mapped_renders(def)) {}

    void add_group(const StudyGroup& g) {
        const ScaledSize size = scaled_size(g, scale_);
        if (g.budget_from) return add_dependent_group(g, size);
        const size_t n = g.sweep_key.empty() ? 1 : g.sweep_values.size();
        for (size_t k = 0; k < n; ++k) {
            json p = g.params;
            json value = nullptr;
            if (!g.sweep_key.empty()) {
                value = g.sweep_values[k];
                p[g.sweep_key] = value;
                if (g.sweep_key == "spp") p.erase("budget");
                if (g.sweep_key == "budget") p.erase("spp");
            }
            for (uint64_t seed : g.seeds) {
                by_group_[g.name].push_back(out_.size());
                out_.push_back(make(g, size, p, k, value, seed));
            }
        }
    }

    std::vector<StudyRender> take() {
        check_rate_renders();
        return std::move(out_);
    }

private:
    // Which (group, index) a maps chart shows: their first seed keeps per-pixel maps.
    static std::set<std::pair<std::string, size_t>> mapped_renders(
        const StudyDefinition& def) {
        std::set<std::pair<std::string, size_t>> mapped;
        for (const json& c : def.charts)
            if (c.value("kind", "") == "maps")
                for (const json& g : c["groups"])
                    mapped.insert({g.get<std::string>(), c["index"].get<size_t>()});
        return mapped;
    }

    void add_dependent_group(const StudyGroup& g, const ScaledSize& size) {
        for (size_t pos : by_group_.at(g.budget_from->group)) {
            const StudyRender& src = out_[pos];
            StudyRender r = make(g, size, g.params, src.index, src.sweep_value, src.seed);
            r.budget_from = g.budget_from;
            r.source_key = src.key;
            if (!g.budget_from->rate_from.empty())
                r.rate_key = g.budget_from->rate_from + "/" + std::to_string(src.index) +
                             "/" + std::to_string(src.seed);
            by_group_[g.name].push_back(out_.size());
            out_.push_back(std::move(r));
        }
    }

    StudyRender make(const StudyGroup& g, const ScaledSize& size, const json& params,
                     size_t index, const json& value, uint64_t seed) const {
        StudyRender r;
        r.group = g.name;
        r.index = index;
        r.sweep_value = value;
        r.scene = g.scene;
        r.width = size.width;
        r.height = size.height;
        r.seed = seed;
        r.key = g.name + "/" + std::to_string(index) + "/" + std::to_string(seed);
        r.save_maps = mapped_.count({g.name, index}) && seed == g.seeds.front();
        r.metric_bucket = uint32_t(std::max<long>(1, std::lround(16 * size.side_ratio)));
        json p = scaled_params(params, size, scale_);
        if (g.budget_from) p["budget"] = size.pixels;  // placeholder until resolve_budget
        try {
            r.strategy = p.get<StrategyParams>();
            validate_parameters(r.strategy, r.width, r.height);
        } catch (const std::invalid_argument& e) {
            throw StudyError("render " + r.key + " at scale " + in_quotes(scale_.name) +
                             ": " + e.what());
        }
        return r;
    }

    // Every equal-time render needs its rate render: same position and seed.
    void check_rate_renders() const {
        std::set<std::string> keys;
        for (const StudyRender& r : out_) keys.insert(r.key);
        for (const StudyRender& r : out_)
            if (!r.rate_key.empty() && !keys.count(r.rate_key))
                throw StudyError("render " + r.key +
                                 ": its rate_from group has no render " + r.rate_key +
                                 " (same sweep position and seed)");
    }

    const StudyScale& scale_;
    const std::set<std::pair<std::string, size_t>> mapped_;
    std::vector<StudyRender> out_;
    std::map<std::string, std::vector<size_t>> by_group_;  // group -> positions in out_
};

}  // namespace

std::vector<StudyRender> expand_study(const StudyDefinition& def,
                                      const StudyScale& scale) {
    PlanBuilder plan(def, scale);
    for (const StudyGroup& g : def.groups) plan.add_group(g);
    std::vector<StudyRender> renders = plan.take();
    for (StudyRender& r : renders) r.denoise = def.denoise;
    return renders;
}

void resolve_budget(StudyRender& r, uint64_t source_samples, double source_seconds,
                    double rate_samples_per_second) {
    if (!r.budget_from) return;
    const uint64_t pixels = uint64_t(r.width) * r.height;
    double budget = double(source_samples);
    if (r.budget_from->match == "seconds")
        budget = source_seconds * rate_samples_per_second;
    budget *= r.budget_from->factor;
    if (!std::isfinite(budget)) budget = double(pixels);
    r.strategy.spp = 0;
    r.strategy.budget = std::max<uint64_t>(pixels, uint64_t(std::llround(budget)));
    r.budget_from.reset();
}

std::string render_spec_json(const StudyRender& r) {
    // nlohmann's json objects keep keys sorted: the dump is canonical.
    json spec = {{"scene", r.scene},
                 {"width", r.width},
                 {"height", r.height},
                 {"seed", r.seed},
                 {"strategy", json(r.strategy)}};
    // Only when set, so the specs of studies that do not denoise stay what they were: a
    // render traced without its first hits has nothing to denoise with.
    if (r.denoise) spec["denoise"] = true;
    return spec.dump();
}

}  // namespace aliquot
