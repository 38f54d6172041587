#include "study.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <functional>
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

const std::set<std::string> kTableKeys = {"title", "group", "compare", "columns", "note"};
const std::set<std::string> kChartKinds = {"error_vs_budget", "error_vs_time", "maps",
                                           "seed_spread", "sweep"};
const std::set<std::string> kConclusionKinds = {"uniform_slope", "beats_everywhere",
                                                "loses_but_bounds_worst", "sweep_effect",
                                                "ranking"};

// Errors name the file and the JSON pointer of the field.
struct Where {
    const std::string& file;
    [[noreturn]] void fail(const std::string& pointer, const std::string& message) const {
        throw StudyError(file + ": " + (pointer.empty() ? "/" : pointer) + ": " +
                         message);
    }
};

std::string in_quotes(const std::string& s) { return "\"" + s + "\""; }

void only_keys(const Where& w, const json& j, const std::string& at,
               const std::set<std::string>& allowed) {
    for (const auto& [key, v] : j.items())
        if (!allowed.count(key))
            w.fail(at + "/" + key, "unknown field " + in_quotes(key));
}

const json& need(const Where& w, const json& j, const std::string& at,
                 const std::string& key) {
    if (!j.contains(key)) w.fail(at + "/" + key, "missing");
    return j.at(key);
}

std::string string_at(const Where& w, const json& v, const std::string& at) {
    if (!v.is_string() || v.get<std::string>().empty())
        w.fail(at, "must be a non-empty string");
    return v.get<std::string>();
}

uint64_t count_at(const Where& w, const json& v, const std::string& at,
                  uint64_t min = 0) {
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0))
        w.fail(at, "must be a whole number of at least " + std::to_string(min));
    const uint64_t n = v.get<uint64_t>();
    if (n < min) w.fail(at, "must be at least " + std::to_string(min));
    return n;
}

double positive_at(const Where& w, const json& v, const std::string& at) {
    if (!v.is_number() || !(v.get<double>() > 0) || !std::isfinite(v.get<double>()))
        w.fail(at, "must be a number greater than 0");
    return v.get<double>();
}

void resolution_at(const Where& w, const json& v, const std::string& at, uint32_t& width,
                   uint32_t& height) {
    const std::string s = string_at(w, v, at);
    unsigned a = 0, b = 0;
    char x = 0, tail = 0;
    if (std::sscanf(s.c_str(), "%u%c%u%c", &a, &x, &b, &tail) != 3 || x != 'x' ||
        a == 0 || b == 0 || a > 8192 || b > 8192)
        w.fail(at, "expected WxH with sides 1..8192, got " + in_quotes(s));
    width = a;
    height = b;
}

std::vector<std::string> string_list_at(const Where& w, const json& v,
                                        const std::string& at) {
    if (!v.is_array() || v.empty()) w.fail(at, "must be a non-empty list of names");
    std::vector<std::string> out;
    for (size_t i = 0; i < v.size(); ++i)
        out.push_back(string_at(w, v[i], at + "/" + std::to_string(i)));
    return out;
}

// The params as a StrategyParams, or a failure naming `at` (the pointer of the params).
StrategyParams strategy_at(const Where& w, const json& params, const std::string& at,
                           uint32_t width, uint32_t height) {
    StrategyParams p;
    try {
        from_json(params, p);
    } catch (const std::invalid_argument& e) {
        w.fail(at, e.what());
    }
    const auto& methods = strategy_methods();
    if (std::find(methods.begin(), methods.end(), p.method) == methods.end()) {
        std::string all;
        for (const auto& m : methods) all += (all.empty() ? "" : ", ") + m;
        w.fail(at + "/method",
               "unknown method " + in_quotes(p.method) + " (valid: " + all + ")");
    }
    try {
        validate(p, width, height);
    } catch (const std::invalid_argument& e) {
        w.fail(at, e.what());
    }
    return p;
}

StudyScale default_scale(const std::string& name) {
    StudyScale s;
    s.name = name;
    if (name == "small") {
        s.max_side = 64;
        s.spp_factor = 0.25;
    } else if (name == "medium") {
        s.max_side = 200;
        s.spp_factor = 0.5;
    }
    return s;
}

void check_group_names(const Where& w, const StudyDefinition& def,
                       const std::vector<std::string>& names, const std::string& at) {
    for (size_t i = 0; i < names.size(); ++i)
        if (!def.group(names[i]))
            w.fail(at + "/" + std::to_string(i),
                   "unknown render group " + in_quotes(names[i]));
}

void parse_tables(const Where& w, StudyDefinition& def, const json& tables) {
    if (!tables.is_array()) w.fail("/tables", "must be a list");
    for (size_t i = 0; i < tables.size(); ++i) {
        const std::string at = "/tables/" + std::to_string(i);
        const json& t = tables[i];
        if (!t.is_object()) w.fail(at, "must be an object");
        only_keys(w, t, at, kTableKeys);
        string_at(w, need(w, t, at, "title"), at + "/title");
        if (t.contains("group") == t.contains("compare"))
            w.fail(at,
                   "give either \"group\" (a sweep table) or \"compare\" (equal budget)");
        if (t.contains("group")) {
            const std::string g = string_at(w, t["group"], at + "/group");
            if (!def.group(g))
                w.fail(at + "/group", "unknown render group " + in_quotes(g));
        } else {
            const auto names = string_list_at(w, t["compare"], at + "/compare");
            check_group_names(w, def, names, at + "/compare");
        }
        if (t.contains("columns")) {
            const auto cols = string_list_at(w, t["columns"], at + "/columns");
            for (size_t c = 0; c < cols.size(); ++c) {
                if (cols[c] == "method" || cols[c] == "seed") continue;
                StrategyParams p;
                if (!json(p).contains(cols[c]))
                    w.fail(at + "/columns/" + std::to_string(c),
                           "unknown strategy parameter " + in_quotes(cols[c]));
            }
        }
    }
    def.tables = tables;
}

void parse_charts(const Where& w, StudyDefinition& def, const json& charts) {
    if (!charts.is_array()) w.fail("/charts", "must be a list");
    for (size_t i = 0; i < charts.size(); ++i) {
        const std::string at = "/charts/" + std::to_string(i);
        const json& c = charts[i];
        if (!c.is_object()) w.fail(at, "must be an object");
        only_keys(w, c, at, {"kind", "title", "groups", "index", "param", "name"});
        const std::string kind = string_at(w, need(w, c, at, "kind"), at + "/kind");
        if (!kChartKinds.count(kind))
            w.fail(at + "/kind", "unknown chart kind " + in_quotes(kind) +
                                     " (valid: error_vs_budget, error_vs_time, maps, "
                                     "seed_spread, sweep)");
        string_at(w, need(w, c, at, "name"), at + "/name");
        if (c.contains("title")) string_at(w, c["title"], at + "/title");
        const auto names = string_list_at(w, need(w, c, at, "groups"), at + "/groups");
        check_group_names(w, def, names, at + "/groups");
        if (kind == "maps") count_at(w, need(w, c, at, "index"), at + "/index");
        if (kind == "sweep") {
            const std::string param =
                string_at(w, need(w, c, at, "param"), at + "/param");
            for (size_t g = 0; g < names.size(); ++g)
                if (def.group(names[g])->sweep_key != param)
                    w.fail(at + "/groups/" + std::to_string(g),
                           "group " + in_quotes(names[g]) + " does not sweep " +
                               in_quotes(param));
        }
    }
    def.charts = charts;
}

void parse_conclusions(const Where& w, StudyDefinition& def, const json& list) {
    if (!list.is_array()) w.fail("/conclusions", "must be a list");
    for (size_t i = 0; i < list.size(); ++i) {
        const std::string at = "/conclusions/" + std::to_string(i);
        const json& c = list[i];
        if (!c.is_object()) w.fail(at, "must be an object");
        const std::string kind = string_at(w, need(w, c, at, "kind"), at + "/kind");
        if (!kConclusionKinds.count(kind))
            w.fail(at + "/kind", "unknown conclusion kind " + in_quotes(kind));
        string_at(w, need(w, c, at, "claim"), at + "/claim");
        for (const char* key : {"group", "winner", "loser"})
            if (c.contains(key)) {
                const std::string g = string_at(w, c[key], at + "/" + key);
                if (!def.group(g))
                    w.fail(at + "/" + key, "unknown render group " + in_quotes(g));
            }
        if (c.contains("groups"))
            check_group_names(w, def, string_list_at(w, c["groups"], at + "/groups"),
                              at + "/groups");
    }
    def.conclusions = list;
}

uint64_t scale_count(uint64_t v, double factor, uint64_t floor) {
    if (v == 0) return 0;
    return std::max<uint64_t>(floor, uint64_t(std::llround(double(v) * factor)));
}

}  // namespace

const StudyGroup* StudyDefinition::group(const std::string& name) const {
    for (const StudyGroup& g : groups)
        if (g.name == name) return &g;
    return nullptr;
}

StudyDefinition parse_study(const std::string& text, const std::string& file) {
    const Where w{file};
    json j;
    try {
        j = json::parse(text);
    } catch (const json::exception& e) {  // parse_error, or out_of_range for 1e309
        throw StudyError(file + ": not valid JSON: " + e.what());
    }
    if (!j.is_object()) w.fail("", "a study must be a JSON object");
    only_keys(w, j, "",
              {"name", "description", "reference_spp", "defaults", "scales", "renders",
               "tables", "charts", "conclusions"});
    StudyDefinition def;
    def.source = j;
    def.name = string_at(w, need(w, j, "", "name"), "/name");
    for (char c : def.name)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_')
            w.fail("/name",
                   "use letters, digits, - and _ only, got " + in_quotes(def.name));
    if (j.contains("description"))
        def.description = string_at(w, j["description"], "/description");
    if (j.contains("reference_spp"))
        def.reference_spp = count_at(w, j["reference_spp"], "/reference_spp", 1);

    // Defaults every group starts from.
    std::string scene = "cornell-box";
    uint32_t width = 0, height = 0;
    std::vector<uint64_t> seeds = {1};
    json base_params = json::object();
    const auto read_seeds = [&](const json& v, const std::string& at) {
        if (!v.is_array() || v.empty()) w.fail(at, "must be a non-empty list of seeds");
        std::vector<uint64_t> out;
        for (size_t i = 0; i < v.size(); ++i) {
            out.push_back(count_at(w, v[i], at + "/" + std::to_string(i)));
            if (std::count(out.begin(), out.end(), out.back()) > 1)
                w.fail(at + "/" + std::to_string(i), "seed listed twice");
        }
        return out;
    };
    if (j.contains("defaults")) {
        const json& d = j["defaults"];
        if (!d.is_object()) w.fail("/defaults", "must be an object");
        only_keys(w, d, "/defaults", {"scene", "resolution", "seeds", "params"});
        if (d.contains("scene")) scene = string_at(w, d["scene"], "/defaults/scene");
        if (d.contains("resolution"))
            resolution_at(w, d["resolution"], "/defaults/resolution", width, height);
        if (d.contains("seeds")) seeds = read_seeds(d["seeds"], "/defaults/seeds");
        if (d.contains("params")) {
            if (!d["params"].is_object()) w.fail("/defaults/params", "must be an object");
            base_params = d["params"];
        }
    }

    for (const char* name : {"small", "medium", "full"})
        def.scales[name] = default_scale(name);
    if (j.contains("scales")) {
        const json& s = j["scales"];
        if (!s.is_object()) w.fail("/scales", "must be an object");
        for (const auto& [name, v] : s.items()) {
            const std::string at = "/scales/" + name;
            if (!v.is_object()) w.fail(at, "must be an object");
            only_keys(w, v, at, {"max_side", "spp_factor", "reference_spp"});
            StudyScale scale =
                def.scales.count(name) ? def.scales[name] : default_scale(name);
            scale.name = name;
            if (v.contains("max_side"))
                scale.max_side = uint32_t(count_at(w, v["max_side"], at + "/max_side"));
            if (v.contains("spp_factor")) {
                scale.spp_factor = positive_at(w, v["spp_factor"], at + "/spp_factor");
                if (scale.spp_factor > 1) w.fail(at + "/spp_factor", "must be at most 1");
            }
            if (v.contains("reference_spp"))
                scale.reference_spp =
                    count_at(w, v["reference_spp"], at + "/reference_spp", 1);
            def.scales[name] = scale;
        }
    }

    const json& renders = need(w, j, "", "renders");
    if (!renders.is_array() || renders.empty())
        w.fail("/renders", "must be a non-empty list");
    for (size_t i = 0; i < renders.size(); ++i) {
        const std::string at = "/renders/" + std::to_string(i);
        const json& r = renders[i];
        if (!r.is_object()) w.fail(at, "must be an object");
        only_keys(w, r, at,
                  {"name", "scene", "resolution", "method", "params", "sweep", "seeds",
                   "budget_from", "note"});
        StudyGroup g;
        g.name = string_at(w, need(w, r, at, "name"), at + "/name");
        if (def.group(g.name))
            w.fail(at + "/name", "render group " + in_quotes(g.name) + " defined twice");
        if (g.name.find('/') != std::string::npos)
            w.fail(at + "/name", "must not contain /");
        g.scene = r.contains("scene") ? string_at(w, r["scene"], at + "/scene") : scene;
        g.width = width;
        g.height = height;
        if (r.contains("resolution"))
            resolution_at(w, r["resolution"], at + "/resolution", g.width, g.height);
        if (g.width == 0)
            w.fail(at + "/resolution", "missing (and no /defaults/resolution)");
        g.seeds = r.contains("seeds") ? read_seeds(r["seeds"], at + "/seeds") : seeds;
        g.params = base_params;
        if (r.contains("params")) {
            if (!r["params"].is_object()) w.fail(at + "/params", "must be an object");
            if (r["params"].contains("method"))
                w.fail(at + "/params/method", "give the method as /renders/N/method");
            for (const auto& [k, v] : r["params"].items()) g.params[k] = v;
        }
        g.params["method"] = string_at(w, need(w, r, at, "method"), at + "/method");
        {
            const auto& methods = strategy_methods();
            const std::string m = g.params["method"];
            if (std::find(methods.begin(), methods.end(), m) == methods.end()) {
                std::string all;
                for (const auto& v : methods) all += (all.empty() ? "" : ", ") + v;
                w.fail(at + "/method",
                       "unknown method " + in_quotes(m) + " (valid: " + all + ")");
            }
        }
        g.params.erase("seed");

        if (r.contains("budget_from")) {
            const json& b = r["budget_from"];
            BudgetSource src;
            if (b.is_string()) {
                src.group = string_at(w, b, at + "/budget_from");
            } else if (b.is_object()) {
                only_keys(w, b, at + "/budget_from", {"group", "match", "rate_from"});
                src.group = string_at(w, need(w, b, at + "/budget_from", "group"),
                                      at + "/budget_from/group");
                if (b.contains("match"))
                    src.match = string_at(w, b["match"], at + "/budget_from/match");
                if (src.match != "samples" && src.match != "seconds")
                    w.fail(at + "/budget_from/match",
                           "must be \"samples\" or \"seconds\", got " +
                               in_quotes(src.match));
                if (src.match == "seconds") {
                    src.rate_from =
                        string_at(w, need(w, b, at + "/budget_from", "rate_from"),
                                  at + "/budget_from/rate_from");
                }
            } else {
                w.fail(at + "/budget_from",
                       "must be a group name or {group, match, rate_from}");
            }
            // Sources must come first: this keeps the order runnable and rules out
            // cycles.
            const StudyGroup* source = def.group(src.group);
            if (!source)
                w.fail(at + "/budget_from",
                       "unknown render group " + in_quotes(src.group) +
                           " (a budget source must be listed before)");
            if (!src.rate_from.empty()) {
                const StudyGroup* rate = def.group(src.rate_from);
                if (!rate)
                    w.fail(at + "/budget_from/rate_from", "unknown render group " +
                                                              in_quotes(src.rate_from) +
                                                              " (must be listed before)");
                if (!rate->budget_from)
                    w.fail(at + "/budget_from/rate_from",
                           "group " + in_quotes(src.rate_from) +
                               " must be an equal-budget group (with budget_from) whose "
                               "renders "
                               "pair with this one's by sweep position and seed");
            }
            if (r.contains("sweep"))
                w.fail(at + "/sweep",
                       "a group with budget_from follows its source's sweep");
            if (r.contains("seeds"))
                w.fail(at + "/seeds", "a group with budget_from uses its source's seeds");
            if (r.contains("scene") || r.contains("resolution"))
                w.fail(
                    at + (r.contains("scene") ? "/scene" : "/resolution"),
                    "a group with budget_from renders its source's scene and resolution");
            for (const char* k : {"spp", "budget"})
                if (g.params.contains(k) && r.contains("params") &&
                    r["params"].contains(k))
                    w.fail(at + "/params/" + k, "the budget comes from budget_from");
            g.params.erase("spp");
            g.params.erase("budget");
            g.scene = source->scene;
            g.width = source->width;
            g.height = source->height;
            g.seeds = source->seeds;
            g.budget_from = src;
            json probe = g.params;
            probe["budget"] =
                uint64_t(g.width) * g.height;  // stands in for the real budget
            strategy_at(w, probe, at + "/params", g.width, g.height);
        } else if (r.contains("sweep")) {
            const json& s = r["sweep"];
            if (!s.is_object() || s.size() != 1)
                w.fail(at + "/sweep",
                       "must be an object with exactly one parameter, e.g. {\"spp\": [1, "
                       "4, 16]}");
            g.sweep_key = s.begin().key();
            const json& values = s.begin().value();
            const std::string vat = at + "/sweep/" + g.sweep_key;
            if (!values.is_array() || values.empty())
                w.fail(vat, "must be a non-empty list of values");
            for (size_t k = 0; k < values.size(); ++k) {
                json p = g.params;
                p[g.sweep_key] = values[k];
                if (g.sweep_key == "spp") p.erase("budget");
                if (g.sweep_key == "budget") p.erase("spp");
                strategy_at(w, p, vat + "/" + std::to_string(k), g.width, g.height);
                g.sweep_values.push_back(values[k]);
            }
        } else {
            strategy_at(w, g.params, at + "/params", g.width, g.height);
        }
        def.groups.push_back(std::move(g));
    }

    parse_tables(w, def, j.value("tables", json::array()));
    parse_charts(w, def, j.value("charts", json::array()));
    parse_conclusions(w, def, j.value("conclusions", json::array()));
    return def;
}

StudyScale study_scale(const StudyDefinition& def, const std::string& name) {
    const auto it = def.scales.find(name);
    if (it == def.scales.end()) {
        std::string all;
        for (const auto& [n, s] : def.scales) all += (all.empty() ? "" : ", ") + n;
        throw StudyError("--scale: unknown scale " + in_quotes(name) +
                         " (this study has " + all + ")");
    }
    return it->second;
}

std::string study_id(const StudyDefinition& def, const StudyScale& scale) {
    return def.name + "@" + scale.name;
}

std::vector<StudyRender> expand_study(const StudyDefinition& def,
                                      const StudyScale& scale) {
    std::vector<StudyRender> out;
    std::map<std::string, std::vector<size_t>> by_group;  // group -> positions in `out`

    // Which (group, index) a maps chart shows: their first seed keeps per-pixel maps.
    std::set<std::pair<std::string, size_t>> mapped;
    for (const json& c : def.charts)
        if (c.value("kind", "") == "maps")
            for (const json& g : c["groups"])
                mapped.insert({g.get<std::string>(), c["index"].get<size_t>()});

    for (const StudyGroup& g : def.groups) {
        uint32_t w = g.width, h = g.height;
        if (scale.max_side && std::max(w, h) > scale.max_side) {
            const double f = double(scale.max_side) / std::max(w, h);
            w = std::max<uint32_t>(1, uint32_t(std::lround(w * f)));
            h = std::max<uint32_t>(1, uint32_t(std::lround(h * f)));
        }
        const uint64_t pixels = uint64_t(w) * h;
        const double pixel_ratio = double(pixels) / (double(g.width) * g.height);
        const double side_ratio = double(std::max(w, h)) / std::max(g.width, g.height);

        const auto scaled = [&](json p) {
            const json defaults = StrategyParams{};
            if (const auto it = kScaledDefaults.find(p.value("method", ""));
                it != kScaledDefaults.end())
                for (const std::string& k : it->second)
                    if (!p.contains(k)) p[k] = defaults[k];
            for (auto& [k, v] : p.items()) {
                if (!v.is_number()) continue;
                if (kSideKeys.count(k))
                    v = std::max<uint64_t>(
                        1, uint64_t(std::llround(v.get<double>() * side_ratio)));
                else if (kPerPixelKeys.count(k))
                    v = scale_count(v.get<uint64_t>(), scale.spp_factor, 1);
                else if (kTotalKeys.count(k))
                    v = scale_count(v.get<uint64_t>(), pixel_ratio * scale.spp_factor,
                                    pixels);
                else if (k == "max_variance" && p.value("method", "") == "dammertz")
                    v = v.get<double>() / std::sqrt(scale.spp_factor);
            }
            return p;
        };
        const auto make = [&](const json& params, size_t index, const json& value,
                              uint64_t seed) {
            StudyRender r;
            r.group = g.name;
            r.index = index;
            r.sweep_value = value;
            r.scene = g.scene;
            r.width = w;
            r.height = h;
            r.seed = seed;
            r.key = g.name + "/" + std::to_string(index) + "/" + std::to_string(seed);
            r.save_maps = mapped.count({g.name, index}) && seed == g.seeds.front();
            r.metric_bucket = uint32_t(std::max<long>(1, std::lround(16 * side_ratio)));
            json p = scaled(params);
            if (g.budget_from) p["budget"] = pixels;  // placeholder until resolve_budget
            try {
                r.strategy = p.get<StrategyParams>();
                validate(r.strategy, w, h);
            } catch (const std::invalid_argument& e) {
                throw StudyError("render " + r.key + " at scale " +
                                 in_quotes(scale.name) + ": " + e.what());
            }
            return r;
        };

        if (g.budget_from) {
            for (size_t pos : by_group.at(g.budget_from->group)) {
                const StudyRender& src = out[pos];
                StudyRender r = make(g.params, src.index, src.sweep_value, src.seed);
                r.budget_from = g.budget_from;
                r.source_key = src.key;
                if (!g.budget_from->rate_from.empty())
                    r.rate_key = g.budget_from->rate_from + "/" +
                                 std::to_string(src.index) + "/" +
                                 std::to_string(src.seed);
                by_group[g.name].push_back(out.size());
                out.push_back(std::move(r));
            }
            continue;
        }
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
                by_group[g.name].push_back(out.size());
                out.push_back(make(p, k, value, seed));
            }
        }
    }
    // Every equal-time render needs its rate render: same position and seed.
    std::set<std::string> keys;
    for (const StudyRender& r : out) keys.insert(r.key);
    for (const StudyRender& r : out)
        if (!r.rate_key.empty() && !keys.count(r.rate_key))
            throw StudyError("render " + r.key + ": its rate_from group has no render " +
                             r.rate_key + " (same sweep position and seed)");
    return out;
}

void resolve_budget(StudyRender& r, uint64_t source_samples, double source_seconds,
                    double rate_samples_per_second) {
    if (!r.budget_from) return;
    const uint64_t pixels = uint64_t(r.width) * r.height;
    double budget = double(source_samples);
    if (r.budget_from->match == "seconds")
        budget = source_seconds * rate_samples_per_second;
    if (!std::isfinite(budget)) budget = double(pixels);
    r.strategy.spp = 0;
    r.strategy.budget = std::max<uint64_t>(pixels, uint64_t(std::llround(budget)));
    r.budget_from.reset();
}

std::string render_spec_json(const StudyRender& r) {
    // nlohmann's json objects keep keys sorted: the dump is canonical.
    return json{{"scene", r.scene},
                {"width", r.width},
                {"height", r.height},
                {"seed", r.seed},
                {"strategy", json(r.strategy)}}
        .dump();
}

}  // namespace aliquot
