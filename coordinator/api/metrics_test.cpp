// FarmMetrics against an in-memory coordinator fed in-process: the text a scrape returns
// names every metric with its fixed labels, and its values follow the farm.
#include "metrics.h"

#include <gtest/gtest.h>

#include <map>
#include <sstream>

#include "scene_loader.h"

namespace aliquot {
namespace {

// Every sample line of a scrape, "name{labels}" -> value; comments (# HELP, # TYPE) left
// out.
std::map<std::string, double> samples(const std::string& text) {
    std::map<std::string, double> out;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        const size_t space = line.rfind(' ');
        out[line.substr(0, space)] = std::stod(line.substr(space + 1));
    }
    return out;
}

RenderSpec small_spec() {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = spec.height = 4;
    spec.strategy.method = "uniform";
    spec.strategy.spp = 2;
    return spec;
}

TEST(FarmMetrics, AnIdleFarmReportsEveryMetricAtZero) {
    Coordinator c(CoordinatorOptions{});
    FarmMetrics metrics(c);
    const std::string text = metrics.scrape();
    const auto s = samples(text);
    for (const char* state : {"queued", "running", "done", "cancelled", "failed"})
        EXPECT_EQ(s.at(std::string("aliquot_renders{state=\"") + state + "\"}"), 0);
    for (const char* state : {"idle", "busy", "lost"})
        EXPECT_EQ(s.at(std::string("aliquot_workers{state=\"") + state + "\"}"), 0);
    EXPECT_EQ(s.at("aliquot_samples_merged_total"), 0);
    EXPECT_EQ(s.at("aliquot_leases_outstanding"), 0);
    EXPECT_EQ(s.at("aliquot_store_write_failures_total"), 0);
    EXPECT_EQ(s.at("aliquot_storage_warning"), 0);
    EXPECT_EQ(s.at("aliquot_render_memory_bytes"), 0);
    EXPECT_EQ(s.at("aliquot_renders_in_memory"), 0);
    EXPECT_EQ(s.at("aliquot_lease_seconds_count{outcome=\"granted\"}"), 0);
    EXPECT_EQ(s.at("aliquot_lease_seconds_count{outcome=\"none\"}"), 0);
    EXPECT_EQ(s.at("aliquot_merge_seconds_count"), 0);
    EXPECT_EQ(s.at("aliquot_rounds_ended_total"), 0);
    EXPECT_EQ(s.at("aliquot_round_end_seconds_total"), 0);
    EXPECT_EQ(s.at("aliquot_round_end_cpu_seconds_total"), 0);
    EXPECT_EQ(s.at("aliquot_round_end_wait_seconds_total"), 0);
    EXPECT_NE(text.find("# TYPE aliquot_samples_merged_total counter"),
              std::string::npos);
    EXPECT_NE(text.find("# TYPE aliquot_merge_seconds histogram"), std::string::npos);
    EXPECT_NE(text.find("# TYPE aliquot_renders gauge"), std::string::npos);
}

TEST(FarmMetrics, ValuesFollowTheFarm) {
    Coordinator c(CoordinatorOptions{});
    FarmMetrics metrics(c);
    c.submit(small_spec());
    const std::string session = c.register_worker("w", 1).session;
    const auto grant = c.lease(session, std::chrono::milliseconds(0));
    ASSERT_TRUE(grant);
    metrics.observe_lease(0.002, true);

    auto s = samples(metrics.scrape());
    EXPECT_EQ(s.at("aliquot_renders{state=\"running\"}"), 1);
    EXPECT_EQ(s.at("aliquot_workers{state=\"busy\"}"), 1);
    EXPECT_EQ(s.at("aliquot_leases_outstanding"), 1);
    EXPECT_EQ(s.at("aliquot_renders_in_memory"), 1);
    EXPECT_EQ(s.at("aliquot_render_memory_bytes"), double(c.memory_in_use()));
    EXPECT_GT(s.at("aliquot_render_memory_bytes"), 0);
    EXPECT_EQ(s.at("aliquot_lease_seconds_count{outcome=\"granted\"}"), 1);
    EXPECT_EQ(s.at("aliquot_lease_seconds_bucket{outcome=\"granted\",le=\"0.005\"}"), 1);
    EXPECT_EQ(s.at("aliquot_lease_seconds_bucket{outcome=\"granted\",le=\"0.001\"}"), 0);

    SampleJobResult result;
    result.rect = grant->job.rect;
    result.pixels.assign(grant->job.counts.size(), PixelSums{});
    for (size_t i = 0; i < grant->job.counts.size(); ++i)
        result.pixels[i].samples = grant->job.counts[i];
    ASSERT_EQ(c.complete(session, grant->lease_id, result).status,
              CompleteStatus::Merged);
    metrics.observe_merge(0.0003);
    metrics.observe_lease(2.0, false);

    s = samples(metrics.scrape());
    EXPECT_EQ(s.at("aliquot_samples_merged_total"), double(result.total_samples()));
    EXPECT_EQ(s.at("aliquot_leases_outstanding"), 0);
    EXPECT_EQ(s.at("aliquot_merge_seconds_count"), 1);
    EXPECT_DOUBLE_EQ(s.at("aliquot_merge_seconds_sum"), 0.0003);
    EXPECT_EQ(s.at("aliquot_lease_seconds_count{outcome=\"none\"}"), 1);
    // That merge ended the render's one round (2 spp over 16 pixels is one job).
    EXPECT_EQ(s.at("aliquot_rounds_ended_total"), 1);
    // The text keeps 16 significant digits.
    EXPECT_DOUBLE_EQ(s.at("aliquot_round_end_seconds_total"), c.round_end_seconds());
    EXPECT_GT(s.at("aliquot_round_end_seconds_total"), 0);
    EXPECT_DOUBLE_EQ(s.at("aliquot_round_end_cpu_seconds_total"),
                     c.round_end_cpu_seconds());
    // The render's last round end: nothing was opened ahead of it, so it counts whole.
    EXPECT_DOUBLE_EQ(s.at("aliquot_round_end_wait_seconds_total"), c.round_end_seconds());
    c.stop();
}

// However many renders and workers come and go, a scrape has the same lines: no label
// takes a render id or a worker name.
TEST(FarmMetrics, AScrapeDoesNotGrowWithTheFarm) {
    Coordinator c(CoordinatorOptions{});
    FarmMetrics metrics(c);
    const size_t lines_before = samples(metrics.scrape()).size();
    for (int i = 0; i < 20; ++i) {
        c.submit(small_spec());
        c.register_worker("worker-" + std::to_string(i), 1);
    }
    EXPECT_EQ(samples(metrics.scrape()).size(), lines_before);
    c.stop();
}

}  // namespace
}  // namespace aliquot
