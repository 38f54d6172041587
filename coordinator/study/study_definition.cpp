#include "study_definition.h"

#include <algorithm>
#include <cctype>
#include <set>

#include "json_field.h"
#include "resolution.h"
#include "seed_json.h"
#include "strategy_params.h"

namespace aliquot {

using nlohmann::json;

namespace {

const std::vector<std::string> kTableKeys = {"title", "group", "compare", "columns",
                                             "note"};
const std::set<std::string> kChartKinds = {"error_vs_budget", "error_vs_time", "maps",
                                           "seed_spread", "sweep"};
const std::set<std::string> kConclusionKinds = {
    "uniform_slope", "beats_everywhere", "loses_but_bounds_worst",
    "sweep_effect",  "ranking",          "near_bound"};

std::string in_quotes(const std::string& s) { return "\"" + s + "\""; }

std::string name_at(const JsonField& f) {
    const std::string s = f.string("must be a non-empty string");
    if (s.empty()) f.fail("must be a non-empty string");
    return s;
}

std::vector<std::string> names_at(const JsonField& f) {
    if (!f.value().is_array() || f.value().empty())
        f.fail("must be a non-empty list of names");
    std::vector<std::string> out;
    for (size_t i = 0; i < f.size(); ++i) out.push_back(name_at(f.at(i)));
    return out;
}

std::vector<uint64_t> seeds_at(const JsonField& f) {
    if (!f.value().is_array() || f.value().empty())
        f.fail("must be a non-empty list of seeds");
    std::vector<uint64_t> out;
    for (size_t i = 0; i < f.size(); ++i) {
        try {
            out.push_back(seed_from_json(f.at(i).value()));
        } catch (const std::invalid_argument& e) {
            f.at(i).fail(e.what());
        }
        if (std::count(out.begin(), out.end(), out.back()) > 1)
            f.at(i).fail("seed listed twice");
    }
    return out;
}

void resolution_at(const JsonField& f, uint32_t& width, uint32_t& height) {
    try {
        const Resolution r = parse_resolution(name_at(f));
        width = r.width;
        height = r.height;
    } catch (const std::invalid_argument& e) {
        f.fail(e.what());
    }
}

void check_method(const JsonField& f, const std::string& method) {
    const auto& methods = strategy_methods();
    if (std::find(methods.begin(), methods.end(), method) != methods.end()) return;
    std::string all;
    for (const auto& m : methods) all += (all.empty() ? "" : ", ") + m;
    f.fail("unknown method " + in_quotes(method) + " (valid: " + all + ")");
}

// `params` as a valid StrategyParams, or a failure at `at`. The params are merged from
// defaults, the group and a sweep value, so `at` is where the group gives them.
void check_strategy(const JsonField& at, const json& params, uint32_t width,
                    uint32_t height) {
    StrategyParams p;
    try {
        from_json(params, p);
    } catch (const std::invalid_argument& e) {
        at.fail(e.what());
    }
    check_method(at.find("method").value_or(at), p.method);
    try {
        validate_parameters(p, width, height);  // an oracle's sigma comes at submission
    } catch (const std::invalid_argument& e) {
        at.fail(e.what());
    }
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

// What every group starts from: /defaults.
struct GroupDefaults {
    std::string scene = "cornell-box";
    uint32_t width = 0, height = 0;
    std::vector<uint64_t> seeds = {1};
    json params = json::object();
};

class StudyParser {
public:
    explicit StudyParser(const JsonField& root) : root_(root) {}

    StudyDefinition parse() {
        root_.expect_object("a study must be a JSON object");
        root_.allow_keys({"name", "description", "reference_spp", "denoise", "defaults",
                          "scales", "renders", "tables", "charts", "conclusions"});
        def_.source = root_.value();
        parse_head();
        if (auto d = root_.find("defaults")) parse_defaults(*d);
        for (const char* name : {"small", "medium", "full"})
            def_.scales[name] = default_scale(name);
        if (auto s = root_.find("scales")) parse_scales(*s);
        const JsonField renders = root_.require("renders");
        if (!renders.value().is_array() || renders.value().empty())
            renders.fail("must be a non-empty list");
        for (size_t i = 0; i < renders.size(); ++i) parse_group(renders.at(i));
        if (auto t = root_.find("tables")) parse_tables(*t);
        if (auto c = root_.find("charts")) parse_charts(*c);
        if (auto c = root_.find("conclusions")) parse_conclusions(*c);
        return std::move(def_);
    }

private:
    void parse_head() {
        const JsonField name = root_.require("name");
        def_.name = name_at(name);
        for (char c : def_.name)
            if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_')
                name.fail("use letters, digits, - and _ only, got " +
                          in_quotes(def_.name));
        if (auto d = root_.find("description")) def_.description = name_at(*d);
        if (auto r = root_.find("reference_spp")) def_.reference_spp = r->whole(1);
        if (auto d = root_.find("denoise")) {
            if (!d->value().is_boolean()) d->fail("expected true or false");
            def_.denoise = d->value().get<bool>();
        }
    }

    void parse_defaults(const JsonField& d) {
        d.expect_object("must be an object");
        d.allow_keys({"scene", "resolution", "seeds", "params"});
        if (auto s = d.find("scene")) defaults_.scene = name_at(*s);
        if (auto r = d.find("resolution"))
            resolution_at(*r, defaults_.width, defaults_.height);
        if (auto s = d.find("seeds")) defaults_.seeds = seeds_at(*s);
        if (auto p = d.find("params")) {
            p->expect_object("must be an object");
            defaults_.params = p->value();
        }
    }

    void parse_scales(const JsonField& s) {
        s.expect_object("must be an object");
        for (const auto& [name, v] : s.members()) {
            v.expect_object("must be an object");
            v.allow_keys({"max_side", "spp_factor", "reference_spp"});
            StudyScale scale =
                def_.scales.count(name) ? def_.scales[name] : default_scale(name);
            scale.name = name;
            if (auto m = v.find("max_side"))
                scale.max_side = uint32_t(m->whole(0, UINT32_MAX));
            if (auto f = v.find("spp_factor")) {
                scale.spp_factor = f->number("must be a number greater than 0");
                if (!(scale.spp_factor > 0)) f->fail("must be a number greater than 0");
                if (scale.spp_factor > 1) f->fail("must be at most 1");
            }
            if (auto r = v.find("reference_spp")) scale.reference_spp = r->whole(1);
            def_.scales[name] = scale;
        }
    }

    void parse_group(const JsonField& r) {
        r.expect_object("must be an object");
        r.allow_keys({"name", "scene", "resolution", "method", "params", "sweep", "seeds",
                      "budget_from", "note"});
        StudyGroup g;
        const JsonField name = r.require("name");
        g.name = name_at(name);
        if (def_.group(g.name))
            name.fail("render group " + in_quotes(g.name) + " defined twice");
        if (g.name.find('/') != std::string::npos) name.fail("must not contain /");
        g.scene = r.has("scene") ? name_at(*r.find("scene")) : defaults_.scene;
        g.width = defaults_.width;
        g.height = defaults_.height;
        if (auto res = r.find("resolution")) resolution_at(*res, g.width, g.height);
        if (g.width == 0)
            throw JsonError(r.pointer() + "/resolution",
                            "missing (and no /defaults/resolution)");
        g.seeds = r.has("seeds") ? seeds_at(*r.find("seeds")) : defaults_.seeds;
        read_params(r, g);
        if (auto b = r.find("budget_from"))
            parse_dependent_group(r, *b, g);
        else if (auto s = r.find("sweep"))
            parse_sweep(*s, g);
        else
            check_strategy(JsonField(g.params, r.pointer() + "/params"), g.params,
                           g.width, g.height);
        def_.groups.push_back(std::move(g));
    }

    // The group's params over the defaults', and its method.
    void read_params(const JsonField& r, StudyGroup& g) {
        g.params = defaults_.params;
        if (auto p = r.find("params")) {
            p->expect_object("must be an object");
            if (auto m = p->find("method"))
                m->fail("give the method as /renders/N/method");
            for (const auto& [k, v] : p->members()) g.params[k] = v.value();
        }
        const JsonField method = r.require("method");
        g.params["method"] = name_at(method);
        check_method(method, g.params["method"]);
        g.params.erase("seed");
    }

    void parse_sweep(const JsonField& s, StudyGroup& g) {
        if (!s.value().is_object() || s.size() != 1)
            s.fail(
                "must be an object with exactly one parameter, e.g. {\"spp\": [1, 4, "
                "16]}");
        const auto [key, values] = s.members().front();
        g.sweep_key = key;
        if (!values.value().is_array() || values.value().empty())
            values.fail("must be a non-empty list of values");
        for (size_t k = 0; k < values.size(); ++k) {
            json p = g.params;
            p[g.sweep_key] = values.value()[k];
            if (g.sweep_key == "spp") p.erase("budget");
            if (g.sweep_key == "budget") p.erase("spp");
            check_strategy(values.at(k), p, g.width, g.height);
            g.sweep_values.push_back(values.value()[k]);
        }
    }

    BudgetSource read_budget_source(const JsonField& b) {
        BudgetSource src;
        if (b.value().is_string()) {
            src.group = name_at(b);
            return src;
        }
        if (!b.value().is_object())
            b.fail("must be a group name or {group, match, rate_from, factor}");
        b.allow_keys({"group", "match", "rate_from", "factor"});
        src.group = name_at(b.require("group"));
        if (auto m = b.find("match")) src.match = name_at(*m);
        if (src.match != "samples" && src.match != "seconds")
            JsonField(b.value(), b.pointer() + "/match")
                .fail("must be \"samples\" or \"seconds\", got " + in_quotes(src.match));
        if (src.match == "seconds") src.rate_from = name_at(b.require("rate_from"));
        if (auto f = b.find("factor")) {
            src.factor = f->number("expected a number");
            if (!(src.factor > 0 && src.factor <= 1024))
                f->fail("must be a number above 0 and at most 1024");
        }
        return src;
    }

    void parse_dependent_group(const JsonField& r, const JsonField& b, StudyGroup& g);
    void parse_tables(const JsonField& tables);
    void parse_charts(const JsonField& charts);
    void parse_conclusions(const JsonField& list);

    void check_group_name(const JsonField& f, const std::string& name) const {
        if (!def_.group(name)) f.fail("unknown render group " + in_quotes(name));
    }
    void check_group_names(const JsonField& list) const {
        const std::vector<std::string> names = names_at(list);
        for (size_t i = 0; i < names.size(); ++i) check_group_name(list.at(i), names[i]);
    }

    const JsonField root_;
    StudyDefinition def_;
    GroupDefaults defaults_;
};

void StudyParser::parse_dependent_group(const JsonField& r, const JsonField& b,
                                        StudyGroup& g) {
    const BudgetSource src = read_budget_source(b);
    // Sources must come first: this keeps the order runnable and rules out cycles.
    const StudyGroup* source = def_.group(src.group);
    if (!source)
        b.fail("unknown render group " + in_quotes(src.group) +
               " (a budget source must be listed before)");
    if (!src.rate_from.empty()) {
        const JsonField rate_at(b.value(), b.pointer() + "/rate_from");
        const StudyGroup* rate = def_.group(src.rate_from);
        if (!rate)
            rate_at.fail("unknown render group " + in_quotes(src.rate_from) +
                         " (must be listed before)");
        if (!rate->budget_from)
            rate_at.fail(
                "group " + in_quotes(src.rate_from) +
                " must be an equal-budget group (with budget_from) whose renders "
                "pair with this one's by sweep position and seed");
    }
    if (auto s = r.find("sweep"))
        s->fail("a group with budget_from follows its source's sweep");
    if (auto s = r.find("seeds"))
        s->fail("a group with budget_from uses its source's seeds");
    for (const char* k : {"scene", "resolution"})
        if (auto f = r.find(k))
            f->fail("a group with budget_from renders its source's scene and resolution");
    for (const char* k : {"spp", "budget"})
        if (auto p = r.find("params"); p && g.params.contains(k) && p->has(k))
            p->require(k).fail("the budget comes from budget_from");
    g.params.erase("spp");
    g.params.erase("budget");
    g.scene = source->scene;
    g.width = source->width;
    g.height = source->height;
    g.seeds = source->seeds;
    g.budget_from = src;
    json probe = g.params;
    probe["budget"] = uint64_t(g.width) * g.height;  // stands in for the real budget
    check_strategy(JsonField(probe, r.pointer() + "/params"), probe, g.width, g.height);
}

void StudyParser::parse_tables(const JsonField& tables) {
    tables.expect_array("must be a list");
    for (size_t i = 0; i < tables.size(); ++i) {
        const JsonField t = tables.at(i);
        t.expect_object("must be an object");
        t.allow_keys(kTableKeys);
        name_at(t.require("title"));
        if (t.has("group") == t.has("compare"))
            t.fail("give either \"group\" (a sweep table) or \"compare\" (equal budget)");
        if (auto g = t.find("group")) check_group_name(*g, name_at(*g));
        if (auto c = t.find("compare")) check_group_names(*c);
        if (auto cols = t.find("columns")) {
            const std::vector<std::string> names = names_at(*cols);
            const json known = StrategyParams{};
            for (size_t c = 0; c < names.size(); ++c)
                if (names[c] != "method" && names[c] != "seed" &&
                    !known.contains(names[c]))
                    cols->at(c).fail("unknown strategy parameter " + in_quotes(names[c]));
        }
    }
    def_.tables = tables.value();
}

void StudyParser::parse_charts(const JsonField& charts) {
    charts.expect_array("must be a list");
    for (size_t i = 0; i < charts.size(); ++i) {
        const JsonField c = charts.at(i);
        c.expect_object("must be an object");
        c.allow_keys({"kind", "title", "groups", "index", "param", "name"});
        const JsonField kind_at = c.require("kind");
        const std::string kind = name_at(kind_at);
        if (!kChartKinds.count(kind))
            kind_at.fail(
                "unknown chart kind " + in_quotes(kind) +
                " (valid: error_vs_budget, error_vs_time, maps, seed_spread, sweep)");
        name_at(c.require("name"));
        if (auto t = c.find("title")) name_at(*t);
        const JsonField groups = c.require("groups");
        check_group_names(groups);
        if (kind == "maps") c.require("index").whole();
        if (kind != "sweep") continue;
        const std::string param = name_at(c.require("param"));
        for (size_t g = 0; g < groups.size(); ++g) {
            const std::string name = groups.value()[g].get<std::string>();
            if (def_.group(name)->sweep_key != param)
                groups.at(g).fail("group " + in_quotes(name) + " does not sweep " +
                                  in_quotes(param));
        }
    }
    def_.charts = charts.value();
}

void StudyParser::parse_conclusions(const JsonField& list) {
    list.expect_array("must be a list");
    for (size_t i = 0; i < list.size(); ++i) {
        const JsonField c = list.at(i);
        c.expect_object("must be an object");
        const JsonField kind_at = c.require("kind");
        const std::string kind = name_at(kind_at);
        if (!kConclusionKinds.count(kind))
            kind_at.fail("unknown conclusion kind " + in_quotes(kind));
        name_at(c.require("claim"));
        for (const char* key : {"group", "winner", "loser", "bound"})
            if (auto g = c.find(key)) check_group_name(*g, name_at(*g));
        if (auto g = c.find("groups")) check_group_names(*g);
    }
    def_.conclusions = list.value();
}

}  // namespace

const StudyGroup* StudyDefinition::group(const std::string& name) const {
    for (const StudyGroup& g : groups)
        if (g.name == name) return &g;
    return nullptr;
}

StudyDefinition parse_study(const std::string& text, const std::string& file) {
    try {
        const json doc = parse_json(text);
        return StudyParser(JsonField(doc)).parse();
    } catch (const JsonError& e) {
        throw StudyError(file + ": " + e.what());
    }
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

}  // namespace aliquot
