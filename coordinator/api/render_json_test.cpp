// One JSON for a render: the HTTP API writes it from the coordinator's RenderInfo and the
// CLI from the same RenderInfo read back off gRPC; the two must be the same document.
#include "render_json.h"

#include <gtest/gtest.h>

#include "render_proto.h"

namespace aliquot {
namespace {

RenderInfo running_render() {
    RenderInfo i;
    i.id = "r-000003";
    i.scene_name = "cornell-box";
    i.method = "uniform";
    i.strategy_json = R"({"method":"uniform","spp":16})";
    i.state = RenderState::Running;
    i.width = 48;
    i.height = 40;
    i.seed = 7;
    i.samples_done = 7680;
    i.samples_planned = 30720;
    i.rounds_done = 1;
    i.seconds = 0.123456789;
    i.samples_per_second = 62208.0;
    i.error_estimate = 0.0159;
    i.created_ms = 1700000000000;
    i.outcome_json = "{}";
    i.rays = 40000;
    return i;
}

TEST(RenderJson, TheCliReadingGrpcPrintsWhatTheHttpApiServes) {
    const RenderInfo info = running_render();
    v1::RenderInfo message;
    to_proto(info, message);
    EXPECT_EQ(render_detail(from_proto(message)), render_detail(info));
}

TEST(RenderJson, SpellsTheStateAndLeavesWhatWasNotMeasuredNull) {
    const nlohmann::json j = render_detail(running_render());
    EXPECT_EQ(j["state"], "running");
    EXPECT_EQ(j["samples_done"], 7680);
    EXPECT_EQ(j["rounds"], 1);
    EXPECT_DOUBLE_EQ(j["progress"].get<double>(), 0.25);
    EXPECT_DOUBLE_EQ(j["seconds"].get<double>(), 0.123457);
    EXPECT_TRUE(j["error_vs_reference"].is_null());
    EXPECT_FALSE(j.contains("error"));  // only a failed render carries one
    EXPECT_EQ(j["strategy"]["spp"], 16);
}

TEST(RenderJson, ADoneRenderIsWhollyProgressedWhateverItsPlan) {
    RenderInfo info = running_render();
    info.state = RenderState::Done;
    EXPECT_EQ(render_summary(info)["progress"], 1.0);
    EXPECT_EQ(render_summary(info)["state"], "done");
}

TEST(RenderJson, ConvergedBucketsAreADammertzRendersProgress) {
    RenderInfo info = running_render();
    info.method = "dammertz";
    const BucketProgress buckets{1, 4, 0.5};
    const nlohmann::json j = render_summary(info, buckets);
    EXPECT_DOUBLE_EQ(j["progress"].get<double>(), 0.5);
    EXPECT_EQ(j["buckets_converged"], 1);
    EXPECT_EQ(j["buckets_total"], 4);
}

}  // namespace
}  // namespace aliquot
