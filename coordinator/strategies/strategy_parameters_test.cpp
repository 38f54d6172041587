#include "strategy_parameters.h"

#include <set>

#include <gtest/gtest.h>

namespace aliquot {
namespace {

// How many members an aggregate has: the most values it can be brace-initialised from.
// None of StrategyParams' members is itself an aggregate, so no brace elision counts a
// member twice.
struct AnyValue {
    template <typename T>
    operator T() const;  // never called: only its type is asked about
};

template <typename T, typename... Values>
constexpr size_t member_count() {
    if constexpr (requires { T{Values{}..., AnyValue{}}; })
        return member_count<T, Values..., AnyValue>();
    else
        return sizeof...(Values);
}

// The message of the std::invalid_argument `f` throws, or "" when it does not throw.
template <typename F>
std::string error_of(F f) {
    try {
        f();
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return "";
}

TEST(StrategyParameters, EveryMemberButMethodAndSigmaIsInTheTable) {
    // A member added to StrategyParams but not to strategy_parameters() would be missing
    // from JSON, the CLI and the dashboard: this fails until the table has it too.
    EXPECT_EQ(member_count<StrategyParams>(), strategy_parameters().size() + 2)
        << "StrategyParams has a member the table does not declare (method and the "
           "oracle's in-process true_sigma are the only ones outside it)";
    std::set<std::string> keys;
    std::vector<StrategyParameter::Member> members;  // pointers to members: no order
    for (const StrategyParameter& p : strategy_parameters()) {
        EXPECT_TRUE(keys.insert(p.key).second) << p.key << " declared twice";
        EXPECT_EQ(std::count(members.begin(), members.end(), p.member), 0)
            << p.key << "'s member taken twice";
        members.push_back(p.member);
        EXPECT_FALSE(p.help.empty()) << p.key;
        EXPECT_FALSE(p.methods.empty()) << p.key;
        for (const std::string& m : p.methods)
            EXPECT_NE(std::find(strategy_methods().begin(), strategy_methods().end(), m),
                      strategy_methods().end())
                << p.key << ": " << m;
        EXPECT_EQ(p.out_of_bounds(StrategyParams{}), "") << p.key << "'s default";
    }
}

// A value other than the default and within bounds, for the round trip.
nlohmann::json other_value(const StrategyParameter& p) {
    const nlohmann::json d = p.default_value();
    switch (p.kind()) {
        case StrategyParameter::Kind::Word:
            return p.words.back() == d ? p.words.front() : p.words.back();
        case StrategyParameter::Kind::Whole:
            return d.get<uint64_t>() == uint64_t(p.min) ? uint64_t(p.min) + 1
                                                        : uint64_t(p.min);
        case StrategyParameter::Kind::Number:
            return d.get<double>() == p.min + 0.25 ? p.min + 0.5 : p.min + 0.25;
    }
    return d;
}

TEST(StrategyParameters, EachRoundTripsThroughJson) {
    for (const StrategyParameter& p : strategy_parameters()) {
        const nlohmann::json value = other_value(p);
        const StrategyParams read = nlohmann::json{
            {"method", p.methods.front()},
            {p.key, value}}.get<StrategyParams>();
        EXPECT_EQ(p.get(read), value) << p.key;
        EXPECT_NE(p.get(read), p.default_value()) << p.key;
        const nlohmann::json written = read;
        EXPECT_EQ(written.at(p.key), value) << p.key;
        EXPECT_EQ(nlohmann::json(written.get<StrategyParams>()), written) << p.key;
    }
}

TEST(StrategyParameters, OutOfBoundsJsonIsRefusedNamingTheKeyAndTheBound) {
    for (const StrategyParameter& p : strategy_parameters()) {
        std::vector<nlohmann::json> bad;
        switch (p.kind()) {
            case StrategyParameter::Kind::Word:
                bad = {"nonsense"};
                break;
            case StrategyParameter::Kind::Whole:
                bad = {uint64_t(p.max) + 1};
                if (p.min > 0) bad.push_back(uint64_t(p.min) - 1);
                break;
            case StrategyParameter::Kind::Number:
                bad = {p.min_open ? p.min : p.min - 1};
                if (!std::isinf(p.max)) bad.push_back(p.max_open ? p.max : p.max + 1);
                break;
        }
        for (const nlohmann::json& v : bad) {
            const std::string e = error_of([&] {
                nlohmann::json{{p.key, v}}.get<StrategyParams>();
            });
            EXPECT_NE(e.find("'" + p.key + "'"), std::string::npos) << p.key << ": " << e;
            EXPECT_NE(e.find(p.bounds()), std::string::npos) << p.key << ": " << e;
            // validate() says the same of a value set in code.
            StrategyParams params;
            params.budget = 100;
            std::visit(
                [&](auto m) {
                    using T = std::remove_reference_t<decltype(params.*m)>;
                    if constexpr (std::is_same_v<T, std::string>)
                        params.*m = v.get<std::string>();
                    else
                        params.*m = v.get<T>();
                },
                p.member);
            if (p.get(params) != v) continue;  // beyond what the member's type holds
            const std::string why = error_of([&] { validate(params, 8, 8); });
            EXPECT_NE(why.find(p.key + " must be " + p.bounds()), std::string::npos)
                << p.key << ": " << why;
        }
    }
}

TEST(StrategyParameters, BoundsReadAsWords) {
    EXPECT_EQ(find_strategy_parameter("sigma_radius")->bounds(),
              "a whole number from 0 to 64");
    EXPECT_EQ(find_strategy_parameter("floor_fraction")->bounds(),
              "a number at least 0 and below 1");
    EXPECT_EQ(find_strategy_parameter("plan_ahead")->bounds(), "a number from 0 to 1");
    EXPECT_EQ(find_strategy_parameter("noise_threshold")->bounds(),
              "a number greater than 0");
    EXPECT_EQ(find_strategy_parameter("error_norm")->bounds(), "seed or paper");
    EXPECT_EQ(find_strategy_parameter("sigma_radius")->flag(), "--sigma-radius");
    EXPECT_EQ(find_strategy_parameter("method"), nullptr);
}

TEST(StrategyParameters, SpecsStoredBeforeTheTableStillParse) {
    // The bytes a coordinator stored for a render (to_json of the struct as it was
    // before the table, every key then known) and an older one with fewer keys.
    const std::string stored =
        R"({"adaptive_min_samples":0,"adaptive_step":16,"alpha":1.0,"bucket_size":16,)"
        R"("budget":0,"error_norm":"seed","floor_fraction":0.5,"initial_spp":16,)"
        R"("max_samples":0,"max_spp":0,"max_variance":0.0064,"method":"optimal",)"
        R"("min_bucket_size":4,"min_spp":4,"noise_threshold":0.01,"plan_ahead":0.0625,)"
        R"("samples_per_iteration":16,"sigma_prior":0,"sigma_radius":0,)"
        R"("split_factor":64.0,"spp":64,"steer_rounds":8})";
    const StrategyParams p = nlohmann::json::parse(stored).get<StrategyParams>();
    EXPECT_EQ(p.method, "optimal");
    EXPECT_EQ(p.plan_ahead, 0.0625);
    // It writes the same bytes back, but for the keys added since, at their defaults
    // (a render stored before them renders as it did).
    std::string written = stored;
    written.insert(written.find(R"("split_factor")"), R"("sigma_self_out":0,)");
    EXPECT_EQ(nlohmann::json(p).dump(), written);
    const StrategyParams old =
        nlohmann::json::parse(R"({"method":"adaptive","spp":8,"alpha":2})")
            .get<StrategyParams>();
    EXPECT_EQ(old.alpha, 2);
    EXPECT_EQ(old.steer_rounds, StrategyParams{}.steer_rounds);
}

TEST(StrategyParameters, MethodsJsonListsEachMethodsOwnParameters) {
    const nlohmann::json methods = methods_json();
    ASSERT_EQ(methods.size(), strategy_methods().size());
    for (const nlohmann::json& m : methods) {
        EXPECT_FALSE(m.at("summary").get<std::string>().empty()) << m["name"];
        EXPECT_EQ(m.at("submittable"), m["name"] != "oracle");
        for (const nlohmann::json& entry : m.at("parameters")) {
            const StrategyParameter* p =
                find_strategy_parameter(entry.at("key").get<std::string>());
            ASSERT_NE(p, nullptr);
            EXPECT_TRUE(p->applies_to(m["name"].get<std::string>()));
            EXPECT_EQ(entry.at("bounds"), p->bounds());
        }
    }
    const auto by_name = [&](const std::string& name) {
        std::set<std::string> keys;
        for (const nlohmann::json& m : methods)
            if (m["name"] == name)
                for (const nlohmann::json& e : m["parameters"]) keys.insert(e["key"]);
        return keys;
    };
    EXPECT_TRUE(by_name("cycles").count("noise_threshold"));
    EXPECT_FALSE(by_name("cycles").count("sigma_radius"));
    EXPECT_TRUE(by_name("optimal").count("plan_ahead"));
    EXPECT_FALSE(by_name("optimal").count("alpha"));
    EXPECT_TRUE(by_name("uniform").count("spp"));
    EXPECT_EQ(by_name("uniform").size(), 4u);  // the budget and the caps
}

TEST(StrategyParameters, SppDefaultsToWhatAMethodThatNeedsABudgetGets) {
    for (const nlohmann::json& m : methods_json())
        for (const nlohmann::json& e : m["parameters"])
            if (e["key"] == "spp") {
                EXPECT_EQ(e["default"],
                          needs_budget(m["name"].get<std::string>()) ? kDefaultSpp : 0)
                    << m["name"];
            }
}

}  // namespace
}  // namespace aliquot
