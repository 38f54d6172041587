// Study definitions: parsing with errors that name the field, scaling, expansion into
// renders, budgets taken from other renders.
#include "study_definition.h"
#include "study_plan.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "store.h"

namespace aliquot {
namespace {

std::string error_of(const std::string& text) {
    try {
        parse_study(text, "studies/x.json");
    } catch (const StudyError& e) {
        return e.what();
    }
    return "";
}

const char* kStudy = R"({
  "name": "t",
  "defaults": {"scene": "cornell-box", "resolution": "600x600", "seeds": [1]},
  "renders": [
    {"name": "u", "method": "uniform", "sweep": {"spp": [1, 16, 256]}},
    {"name": "d", "method": "dammertz", "params": {"samples_per_iteration": 16,
     "max_samples": 2949120000}, "sweep": {"max_variance": [0.0512, 0.0064]}, "seeds": [1, 2]},
    {"name": "a", "method": "adaptive", "params": {"initial_spp": 128, "spp": 2000},
     "sweep": {"alpha": [0.25, 1]}},
    {"name": "eu", "method": "uniform", "budget_from": "d"},
    {"name": "eo", "method": "optimal", "budget_from": {"group": "d", "match": "seconds",
     "rate_from": "eu"}}
  ],
  "tables": [{"title": "Uniform", "group": "u", "columns": ["spp"]},
             {"title": "Equal budget", "compare": ["eu", "d"]}],
  "charts": [{"kind": "maps", "name": "maps", "groups": ["eu", "d"], "index": 1}]
})";

TEST(Study, ANumberTooLargeForADoubleIsAStudyError) {
    // nlohmann's parser throws out_of_range, not parse_error, for it (found by fuzz/).
    const std::string error = error_of(R"({"name": "t", "reference_spp": 1e309})");
    EXPECT_NE(error.find("studies/x.json: invalid JSON"), std::string::npos) << error;
}

TEST(Study, ExpandsSweepsTimesSeedsInDependencyOrder) {
    const StudyDefinition def = parse_study(kStudy, "x.json");
    const std::vector<StudyRender> r = expand_study(def, study_scale(def, "full"));
    // u: 3, d: 2 values x 2 seeds, a: 2, eu and eo: one per d render.
    ASSERT_EQ(r.size(), 3u + 4 + 2 + 4 + 4);
    EXPECT_EQ(r[0].key, "u/0/1");
    EXPECT_EQ(r[0].strategy.spp, 1u);
    EXPECT_EQ(r[3].key, "d/0/1");
    EXPECT_EQ(r[4].key, "d/0/2");
    EXPECT_EQ(r[9].key, "eu/0/1");
    EXPECT_EQ(r[9].source_key, "d/0/1");
    EXPECT_TRUE(r[9].budget_from.has_value());
    EXPECT_EQ(r[13].key, "eo/0/1");
    EXPECT_EQ(r[13].rate_key, "eu/0/1");
    EXPECT_EQ(r[0].width, 600u);
}

TEST(Study, SmallScaleShrinksResolutionAndPerPixelCounts) {
    const StudyDefinition def = parse_study(kStudy, "x.json");
    const StudyScale small = study_scale(def, "small");  // 64 px side, spp x 1/4
    const std::vector<StudyRender> r = expand_study(def, small);
    EXPECT_EQ(r[0].width, 64u);
    EXPECT_EQ(r[0].height, 64u);
    EXPECT_EQ(r[0].strategy.spp, 1u);  // 1/4 spp rounds up to the floor of 1
    EXPECT_EQ(r[1].strategy.spp, 4u);
    EXPECT_EQ(r[2].strategy.spp, 64u);
    // Dammertz: S x 1/4, V x 2 (reached at a quarter of the samples), the total cap by
    // the pixel ratio times 1/4.
    EXPECT_EQ(r[3].strategy.samples_per_iteration, 4u);
    EXPECT_DOUBLE_EQ(r[3].strategy.max_variance, 0.1024);
    EXPECT_EQ(r[3].strategy.max_samples,
              uint64_t(std::llround(2949120000.0 * 4096 / 360000 / 4)));
    // Adaptive's max_variance is a pixel-value range, not an error: unscaled.
    EXPECT_EQ(r[7].strategy.initial_spp, 32u);
    EXPECT_EQ(r[7].strategy.spp, 500u);
    EXPECT_DOUBLE_EQ(r[7].strategy.max_variance, StrategyParams{}.max_variance);
    // Buckets cover the same part of the image: 16 px of 600 is 2 px of 64, a default
    // included; the metric's buckets follow. Dammertz's smallest side is a cost guard:
    // kept.
    EXPECT_EQ(r[7].strategy.bucket_size, 2u);
    EXPECT_EQ(r[3].strategy.min_bucket_size, StrategyParams{}.min_bucket_size);
    EXPECT_EQ(r[3].metric_bucket, 2u);
    // A uniform render keeps the defaults it does not use, so its spec does not change.
    EXPECT_EQ(r[0].strategy.bucket_size, StrategyParams{}.bucket_size);
    EXPECT_EQ(r[0].strategy.min_spp, StrategyParams{}.min_spp);
}

TEST(Study, FullScaleKeepsTheFileAsWritten) {
    const StudyDefinition def = parse_study(kStudy, "x.json");
    const std::vector<StudyRender> r = expand_study(def, study_scale(def, "full"));
    EXPECT_EQ(r[3].strategy.samples_per_iteration, 16u);
    EXPECT_DOUBLE_EQ(r[3].strategy.max_variance, 0.0512);
    EXPECT_EQ(r[7].strategy.spp, 2000u);
}

TEST(Study, ScalesKeepTheAspectRatio) {
    const StudyDefinition def = parse_study(
        R"({"name": "w", "renders": [{"name": "u", "method": "uniform",
            "resolution": "400x100", "params": {"spp": 4}}]})",
        "w.json");
    const StudyRender r = expand_study(def, study_scale(def, "small"))[0];
    EXPECT_EQ(r.width, 64u);
    EXPECT_EQ(r.height, 16u);
}

TEST(Study, BudgetFromTakesTheSourceSamplesOrItsTimeAtTheRateRendersSpeed) {
    const StudyDefinition def = parse_study(kStudy, "x.json");
    std::vector<StudyRender> r = expand_study(def, study_scale(def, "full"));
    resolve_budget(r[9], 12345678, 10.0, 0.0);
    EXPECT_EQ(r[9].strategy.budget, 12345678u);
    EXPECT_FALSE(r[9].budget_from.has_value());
    resolve_budget(r[13], 12345678, 2.0, 1e6);  // 2 s at 1 M samples/s
    EXPECT_EQ(r[13].strategy.budget, 2000000u);
    // Never below one sample per pixel.
    StudyRender tiny = expand_study(def, study_scale(def, "full"))[10];
    resolve_budget(tiny, 3, 0, 0);
    EXPECT_EQ(tiny.strategy.budget, 360000u);
}

TEST(Study, ABudgetFactorScalesTheSourceAndADenoisingStudyTracesFirstHits) {
    const std::string text = R"({"name": "d", "denoise": true,
        "defaults": {"scene": "cornell-box", "resolution": "8x8", "seeds": [1]},
        "renders": [
            {"name": "u", "method": "uniform", "sweep": {"spp": [4]}},
            {"name": "u15", "method": "uniform",
             "budget_from": {"group": "u", "factor": 1.5}}]})";
    const StudyDefinition def = parse_study(text, "d.json");
    std::vector<StudyRender> r = expand_study(def, study_scale(def, "full"));
    ASSERT_EQ(r.size(), 2u);
    resolve_budget(r[1], 1000, 0, 0);
    EXPECT_EQ(r[1].strategy.budget, 1500u);
    EXPECT_TRUE(r[0].denoise);
    // Its spec says so, so a render traced without its first hits is not reused.
    EXPECT_NE(render_spec_json(r[0]).find("\"denoise\":true"), std::string::npos);
    EXPECT_THROW(parse_study(R"({"name": "d", "denoise": 1, "renders": [
        {"name": "u", "method": "uniform", "scene": "cornell-box", "spp": 4}]})",
                             "d.json"),
                 StudyError);
}

TEST(Study, MapsChartsMarkTheirRendersFirstSeedOnly) {
    const StudyDefinition def = parse_study(kStudy, "x.json");
    for (const StudyRender& r : expand_study(def, study_scale(def, "full"))) {
        const bool want =
            (r.group == "eu" || r.group == "d") && r.index == 1 && r.seed == 1;
        EXPECT_EQ(r.save_maps, want) << r.key;
    }
}

TEST(Study, SpecJsonChangesWithAnyParameterAndNotOtherwise) {
    const StudyDefinition def = parse_study(kStudy, "x.json");
    const std::vector<StudyRender> a = expand_study(def, study_scale(def, "full"));
    const std::vector<StudyRender> b = expand_study(def, study_scale(def, "full"));
    EXPECT_EQ(render_spec_json(a[1]), render_spec_json(b[1]));
    StudyRender c = a[1];
    c.strategy.spp += 1;
    EXPECT_NE(render_spec_json(a[1]), render_spec_json(c));
    EXPECT_NE(render_spec_json(a[3]), render_spec_json(a[4]));  // seeds differ
}

TEST(Study, ErrorsNameTheFileAndTheField) {
    std::string text = kStudy;
    text.replace(text.find("\"method\": \"adaptive\""), 20, "\"method\": \"magik\"");
    EXPECT_EQ(error_of(text).rfind(
                  "studies/x.json: /renders/2/method: unknown method \"magik\"", 0),
              0u)
        << error_of(text);

    EXPECT_EQ(error_of("{\"name\": \"x\"}"),
              "studies/x.json: /: missing key \"renders\"");
    EXPECT_EQ(error_of("[1]"), "studies/x.json: /: a study must be a JSON object");
    EXPECT_NE(error_of("{").find("studies/x.json: invalid JSON at line 1"),
              std::string::npos);
}

TEST(Study, RejectsEachKindOfMistakeAtItsPointer) {
    const auto bad = [](const std::string& renders, const std::string& rest = "") {
        return error_of(
            R"({"name": "x", "defaults": {"resolution": "8x8"}, "renders": )" + renders +
            rest + "}");
    };
    EXPECT_NE(bad(R"([{"name": "u", "method": "uniform", "params": {"spp": -1}}])")
                  .find("/renders/0/params: strategy parameter 'spp'"),
              std::string::npos);
    EXPECT_NE(
        bad(R"([{"name": "u", "method": "uniform", "params": {"colour": 1, "spp": 1}}])")
            .find("/renders/0/params: strategy parameter 'colour': unknown key"),
        std::string::npos);
    EXPECT_NE(bad(R"([{"name": "u", "method": "uniform", "sweep": {"spp": [1, 0]}}])")
                  .find("/renders/0/sweep/spp/1:"),
              std::string::npos);
    EXPECT_NE(
        bad(R"([{"name": "u", "method": "uniform", "sweep": {"spp": [1], "budget": [2]}}])")
            .find("/renders/0/sweep: must be an object with exactly one parameter"),
        std::string::npos);
    EXPECT_NE(bad(R"([{"name": "e", "method": "uniform", "budget_from": "nope"}])")
                  .find("/renders/0/budget_from: unknown render group \"nope\""),
              std::string::npos);
    EXPECT_NE(
        bad(R"([{"name": "u", "method": "uniform", "params": {"spp": 1}, "resolution": "0x3"}])")
            .find("/renders/0/resolution: expected WxH"),
        std::string::npos);
    EXPECT_NE(
        bad(R"([{"name": "u", "method": "uniform", "params": {"spp": 1}, "seeds": [1, 1]}])")
            .find("/renders/0/seeds/1: seed listed twice"),
        std::string::npos);
    EXPECT_NE(bad(R"([{"name": "u", "method": "uniform", "params": {"spp": 1}}])",
                  R"(, "tables": [{"title": "t", "group": "v"}])")
                  .find("/tables/0/group: unknown render group \"v\""),
              std::string::npos);
    EXPECT_NE(bad(R"([{"name": "u", "method": "uniform", "params": {"spp": 1}}])",
                  R"(, "charts": [{"kind": "pie", "name": "p", "groups": ["u"]}])")
                  .find("/charts/0/kind: unknown chart kind \"pie\""),
              std::string::npos);
    EXPECT_NE(
        bad(R"([{"name": "u", "method": "uniform", "params": {"spp": 1}, "colour": 2}])")
            .find("/renders/0/colour: unknown key (expected name, scene, resolution"),
        std::string::npos);
}

TEST(Study, AnEqualTimeRenderNeedsItsRateRenderAtTheSamePositionAndSeed) {
    const char* text = R"({"name": "t", "defaults": {"resolution": "8x8"}, "renders": [
        {"name": "d1", "method": "dammertz", "seeds": [1]},
        {"name": "u1", "method": "uniform", "budget_from": "d1"},
        {"name": "d2", "method": "dammertz", "seeds": [1, 2]},
        {"name": "ut", "method": "uniform",
         "budget_from": {"group": "d2", "match": "seconds", "rate_from": "u1"}}]})";
    const StudyDefinition def = parse_study(text, "t.json");
    try {
        expand_study(def, study_scale(def, "full"));
        FAIL();
    } catch (const StudyError& e) {
        EXPECT_NE(std::string(e.what()).find(
                      "render ut/0/2: its rate_from group has no render u1/0/2"),
                  std::string::npos)
            << e.what();
    }
}

TEST(Study, UnknownScaleIsAnErrorListingTheKnownOnes) {
    const StudyDefinition def = parse_study(kStudy, "x.json");
    try {
        study_scale(def, "huge");
        FAIL();
    } catch (const StudyError& e) {
        EXPECT_NE(std::string(e.what()).find("full, medium, small"), std::string::npos)
            << e.what();
    }
}

TEST(Study, AFileMayRedefineAScale) {
    const StudyDefinition def = parse_study(
        R"({"name": "s", "scales": {"small": {"max_side": 8, "spp_factor": 0.5, "reference_spp": 32}},
            "renders": [{"name": "u", "method": "uniform", "resolution": "16x16",
                         "sweep": {"spp": [8]}}]})",
        "s.json");
    const StudyScale s = study_scale(def, "small");
    EXPECT_EQ(s.reference_spp, 32u);
    const StudyRender r = expand_study(def, s)[0];
    EXPECT_EQ(r.width, 8u);
    EXPECT_EQ(r.strategy.spp, 4u);
}

TEST(StudyStore, ResultsAreUpsertedByKeyAndReadInFirstRecordedOrder) {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("aliquot_study_store_" + std::to_string(getpid()));
    std::filesystem::remove_all(dir);
    {
        RunStore store(dir);
        store.put_study({"t@small", "t", "{}", 1});
        store.put_study(
            {"t@small", "t", R"({"v":2})", 1});  // a re-run replaces the definition
        EXPECT_EQ(store.get_study("t@small")->definition_json, R"({"v":2})");
        StudyResult a;
        a.study_id = "t@small";
        a.render_key = "u/0/1";
        a.spec_json = "{}";
        a.origin = "embedded";
        a.remote_id = "r-000001";
        a.state = "submitted";
        store.put_study_result(a);
        StudyResult b = a;
        b.render_key = "u/1/1";
        store.put_study_result(b);
        a.state = "done";
        a.samples = 64;
        a.mean_abs = 0.5;
        a.p99_bucket = std::nan("");  // stored as NULL, not refused
        store.put_study_result(a);
        const std::vector<StudyResult> rows = store.study_results("t@small");
        ASSERT_EQ(rows.size(), 2u);
        EXPECT_EQ(rows[0].render_key, "u/0/1");
        EXPECT_EQ(rows[0].state, "done");
        EXPECT_EQ(rows[0].samples, 64);
        EXPECT_EQ(rows[0].mean_abs, 0.5);
        EXPECT_FALSE(rows[0].p99_bucket.has_value());
        EXPECT_EQ(rows[1].state, "submitted");
        a.state = "lost";
        EXPECT_THROW(store.put_study_result(a), StoreError);
    }
    std::filesystem::remove_all(dir);
}

TEST(Study, EveryStudyOfTheRepositoryParsesAndExpandsAtEveryScale) {
    // The study files are run by hand (minutes to hours); a typo must fail here first.
    namespace fs = std::filesystem;
    size_t files = 0;
    for (const auto& entry :
         fs::directory_iterator(fs::path(ALIQUOT_SOURCE_DIR) / "studies")) {
        if (entry.path().extension() != ".json") continue;
        ++files;
        std::ifstream in(entry.path());
        const std::string text((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
        const StudyDefinition def = parse_study(text, entry.path().string());
        for (const auto& [name, scale] : def.scales)
            EXPECT_FALSE(expand_study(def, scale).empty()) << entry.path() << " " << name;
    }
    EXPECT_GE(files, 3u);
}

}  // namespace
}  // namespace aliquot
