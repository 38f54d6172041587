#include "strategy_params.h"

#include <gtest/gtest.h>

#include "strategy.h"

namespace aliquot {
namespace {

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

StrategyParams with_budget(const char* method) {
    StrategyParams p;
    p.method = method;
    p.budget = 1000;
    return p;
}

TEST(StrategyParams, RoundTripsThroughJson) {
    StrategyParams p;
    p.method = "dammertz";
    p.max_variance = 0.0032;
    p.samples_per_iteration = 32;
    p.split_factor = 256;
    p.error_norm = "paper";
    p.max_spp = 1000;
    p.max_samples = 123456789;
    const StrategyParams q = nlohmann::json(p).get<StrategyParams>();
    EXPECT_EQ(nlohmann::json(q), nlohmann::json(p));
}

TEST(StrategyParams, MissingKeysKeepTheirDefaults) {
    const StrategyParams p =
        nlohmann::json{{"method", "adaptive"}, {"budget", 5}}.get<StrategyParams>();
    EXPECT_EQ(p.method, "adaptive");
    EXPECT_EQ(p.budget, 5u);
    EXPECT_EQ(p.bucket_size, 16u);
    EXPECT_EQ(p.split_factor, 64);
    EXPECT_EQ(p.initial_spp, 16u);
}

TEST(StrategyParams, UnknownKeyIsRejectedByName) {
    const std::string e = error_of([] {
        nlohmann::json{{"method", "uniform"}, {"max_varianc", 1}}.get<StrategyParams>();
    });
    EXPECT_NE(e.find("'max_varianc'"), std::string::npos) << e;
}

TEST(StrategyParams, WrongTypesAndNegativeCountsAreRejectedByName) {
    EXPECT_NE(error_of([] {
                  nlohmann::json{{"alpha", "one"}}.get<StrategyParams>();
              }).find("'alpha'"),
              std::string::npos);
    EXPECT_NE(error_of([] {
                  nlohmann::json{{"budget", -5}}.get<StrategyParams>();
              }).find("'budget'"),
              std::string::npos);
    EXPECT_NE(error_of([] {
                  nlohmann::json{{"max_spp", 1e10}}.get<StrategyParams>();
              }).find("'max_spp'"),
              std::string::npos);
    EXPECT_NE(error_of([] {
                  nlohmann::json{{"spp", 2.5}}.get<StrategyParams>();
              }).find("'spp'"),
              std::string::npos);
    const nlohmann::json whole_double = {{"spp", 16.0}};
    EXPECT_EQ(whole_double.get<StrategyParams>().spp, 16u);
    EXPECT_NE(error_of([] {
                  nlohmann::json{{"max_spp", 5000000000u}}.get<StrategyParams>();
              }).find("'max_spp'"),
              std::string::npos);
}

TEST(StrategyParams, UnknownMethodListsTheValidOnes) {
    StrategyParams p = with_budget("importance");
    const std::string e = error_of([&] { validate(p, 8, 8); });
    EXPECT_NE(e.find("'importance'"), std::string::npos) << e;
    for (const std::string& m : strategy_methods())
        EXPECT_NE(e.find(m), std::string::npos) << e;
}

TEST(StrategyParams, ValidationNamesTheParameterThatIsWrong) {
    const std::vector<std::pair<std::function<void(StrategyParams&)>, std::string>>
        cases = {
            {[](StrategyParams& p) { p.budget = 0; }, "budget"},
            {[](StrategyParams& p) { p.spp = 4; }, "spp and budget"},
            {[](StrategyParams& p) { p.budget = uint64_t(1) << 60; }, "budget"},
            {[](StrategyParams& p) { p.alpha = -1; }, "alpha"},
            {[](StrategyParams& p) { p.alpha = std::nan(""); }, "alpha"},
            {[](StrategyParams& p) { p.max_variance = 0; }, "max_variance"},
            {[](StrategyParams& p) { p.max_variance = std::nan(""); }, "max_variance"},
            {[](StrategyParams& p) { p.samples_per_iteration = 0; },
             "samples_per_iteration"},
            {[](StrategyParams& p) { p.split_factor = 0.5; }, "split_factor"},
            {[](StrategyParams& p) { p.bucket_size = 0; }, "bucket_size"},
            {[](StrategyParams& p) { p.min_bucket_size = 0; }, "min_bucket_size"},
            {[](StrategyParams& p) { p.error_norm = "l2"; }, "error_norm"},
            {[](StrategyParams& p) { p.initial_spp = 64, p.max_spp = 32; },
             "initial_spp"},
        };
    for (const auto& [change, name] : cases) {
        StrategyParams p = with_budget("adaptive");
        change(p);
        const std::string e = error_of([&] { validate(p, 8, 8); });
        EXPECT_NE(e.find(name), std::string::npos)
            << "want '" << name << "', got '" << e << "'";
    }
}

TEST(StrategyParams, BudgetThatGivesMoreThanUint32SamplesPerPixelIsRejected) {
    StrategyParams p = with_budget("uniform");
    p.budget = uint64_t(UINT32_MAX) * 4 + 4;
    EXPECT_NE(error_of([&] { validate(p, 2, 2); }).find("per pixel"), std::string::npos);
    p.budget = 0;
    p.spp = uint64_t(UINT32_MAX) + 1;
    EXPECT_NE(error_of([&] { validate(p, 2, 2); }).find("spp"), std::string::npos);
}

TEST(StrategyParams, DammertzNeedsNoBudget) {
    StrategyParams p;
    p.method = "dammertz";
    EXPECT_NO_THROW(validate(p, 8, 8));
    p.method = "optimal";
    EXPECT_THROW(validate(p, 8, 8), std::invalid_argument);
}

TEST(StrategyParams, EmptyImageIsRejected) {
    EXPECT_THROW(validate(with_budget("uniform"), 0, 8), std::invalid_argument);
}

TEST(StrategyParams, MakeStrategyBuildsEveryMethod) {
    for (const std::string& method : strategy_methods()) {
        StrategyParams p = with_budget("uniform");
        p.method = method;
        if (method == "oracle")
            p.true_sigma = std::make_shared<const std::vector<float>>(100, 0.5f);
        const auto strategy = make_strategy(p, 10, 10);
        ASSERT_TRUE(strategy);
        EXPECT_EQ(strategy->name(), method);
    }
    EXPECT_THROW(make_strategy(with_budget("nope"), 10, 10), std::invalid_argument);
}

TEST(StrategyParams, OracleWithoutItsSigmaIsRefusedSayingWhereSigmaComesFrom) {
    StrategyParams p = with_budget("oracle");
    try {
        validate(p, 10, 10);
        FAIL() << "an oracle without sigma was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("--sigma"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("coordinator"), std::string::npos);
    }
    EXPECT_NO_THROW(validate_parameters(p, 10, 10));  // a plan attaches sigma later
    p.true_sigma = std::make_shared<const std::vector<float>>(99, 0.5f);
    EXPECT_THROW(validate(p, 10, 10), std::invalid_argument);  // wrong size
    p.true_sigma = std::make_shared<const std::vector<float>>(100, -1.0f);
    EXPECT_THROW(validate(p, 10, 10), std::invalid_argument);  // negative
    p.true_sigma = std::make_shared<const std::vector<float>>(100, 0.5f);
    EXPECT_NO_THROW(validate(p, 10, 10));
}

TEST(StrategyParams, SigmaCannotArriveInJson) {
    StrategyParams p;
    try {
        from_json(nlohmann::json{{"method", "oracle"}, {"sigma", {1, 2}}}, p);
        FAIL() << "sigma was read from JSON";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("'sigma'"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(nlohmann::json(p).contains("sigma"));
}

TEST(StrategyParams, CyclesAndRobustSigmaParametersAreCheckedByName) {
    auto message = [](StrategyParams p) {
        try {
            validate(p, 10, 10);
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    StrategyParams p;
    p.method = "cycles";
    EXPECT_EQ(message(p), "");  // like Dammertz, Cycles needs no budget
    p.noise_threshold = 0;
    EXPECT_NE(message(p).find("noise_threshold"), std::string::npos);
    p.noise_threshold = std::nan("");
    EXPECT_NE(message(p).find("noise_threshold"), std::string::npos);
    p.noise_threshold = 0.01;
    p.adaptive_step = 0;
    EXPECT_NE(message(p).find("adaptive_step"), std::string::npos);
    p.adaptive_step = 16;
    p.max_spp = 8;
    p.adaptive_min_samples = 9;
    EXPECT_NE(message(p).find("adaptive_min_samples"), std::string::npos);
    p = with_budget("optimal");
    p.sigma_radius = 65;
    EXPECT_NE(message(p).find("sigma_radius"), std::string::npos);
    p.sigma_radius = 1;
    p.sigma_prior = (1u << 24) + 1;
    EXPECT_NE(message(p).find("sigma_prior"), std::string::npos);
    p.sigma_prior = 16;
    for (double f : {-0.1, 1.0, std::nan("")}) {
        p.floor_fraction = f;
        EXPECT_NE(message(p).find("floor_fraction"), std::string::npos) << f;
    }
    p.floor_fraction = 0.5;
    p.steer_rounds = 65;
    EXPECT_NE(message(p).find("steer_rounds"), std::string::npos);
    p.steer_rounds = 64;
    for (double f : {-0.1, 1.5, std::nan("")}) {
        p.plan_ahead = f;
        EXPECT_NE(message(p).find("plan_ahead"), std::string::npos) << f;
    }
    p.plan_ahead = 1;
    EXPECT_NO_THROW(validate(p, 8, 8));
    StrategyParams read;
    from_json(nlohmann::json{{"method", "cycles"},
                             {"noise_threshold", 0.05},
                             {"adaptive_min_samples", 8},
                             {"adaptive_step", 4},
                             {"sigma_radius", 2},
                             {"sigma_prior", 16},
                             {"floor_fraction", 0.5},
                             {"steer_rounds", 3},
                             {"plan_ahead", 0.25}},
              read);
    EXPECT_EQ(read.noise_threshold, 0.05);
    EXPECT_EQ(read.adaptive_min_samples, 8u);
    EXPECT_EQ(read.adaptive_step, 4u);
    EXPECT_EQ(read.sigma_radius, 2u);
    EXPECT_EQ(read.sigma_prior, 16u);
    EXPECT_EQ(read.floor_fraction, 0.5);
    EXPECT_EQ(read.steer_rounds, 3u);
    EXPECT_EQ(read.plan_ahead, 0.25);
    EXPECT_EQ(StrategyParams{}.steer_rounds, 8u);  // the default, docs/RESULTS.md
}

}  // namespace
}  // namespace aliquot
