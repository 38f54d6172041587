// A render that keeps first-hit sums (RenderSpec::aux, issue 34): its jobs ask for them,
// its results merge them, its checkpoints keep them, and a render that does not keep
// them is what it was.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

#include "checkpoint.h"
#include "render_session.h"
#include "scene_loader.h"

namespace aliquot {
namespace {

std::filesystem::path temp_file(const char* name) {
    return std::filesystem::temp_directory_path() /
           (std::string("aliquot-aux-") + std::to_string(getpid()) + "-" + name);
}

// What a worker returns for `job` without tracing: colour 0.5 a sample, and with
// job.aux an albedo of 0.25 and a normal of +y a sample.
SampleJobResult fake_result(const SampleJob& job) {
    SampleJobResult r;
    r.rect = job.rect;
    r.pixels.resize(job.rect.size());
    if (job.aux) r.first_hits.resize(job.rect.size());
    for (size_t i = 0; i < r.pixels.size(); ++i) {
        const double n = double(job.counts[i]);
        r.pixels[i].samples = job.counts[i];
        r.pixels[i].even[0] = 0.5 * n;
        if (job.aux) {
            for (int c = 0; c < 3; ++c) r.first_hits[i].albedo[c] = 0.25 * n;
            r.first_hits[i].normal[1] = n;
        }
    }
    return r;
}

RenderSpec small_spec(bool aux) {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = 16;
    spec.height = 8;
    spec.strategy.method = "uniform";
    spec.strategy.spp = 2;
    spec.aux = aux;
    return spec;
}

// Leases every job of the session and completes it with `make`'s result, until done.
template <typename Make>
void run(RenderSession& s, Make make) {
    const auto far = RenderSession::Clock::now() + std::chrono::hours(1);
    uint64_t lease = 1;
    while (auto job = s.issue(lease, "w", far)) {
        ASSERT_EQ(s.complete(lease, "w", make(*job)).status, CompleteStatus::Merged);
        ++lease;
    }
    ASSERT_EQ(s.state(), RenderState::Done);
}

// Starts the session and leases its first job to "w" as lease 1.
std::optional<SampleJob> start_and_lease(RenderSession& s) {
    s.start();
    return s.issue(1, "w", RenderSession::Clock::now() + std::chrono::hours(1));
}

TEST(AuxRender, ItsJobsAskForFirstHitsAndItsImageHasTheirMeans) {
    RenderSession s("r", small_spec(true), 0);
    s.start();
    run(s, [](const SampleJob& job) {
        EXPECT_TRUE(job.aux);
        return fake_result(job);
    });
    const Image albedo = s.aux().albedo(s.merged());
    const Image normal = s.aux().normal(s.merged());
    ASSERT_EQ(albedo.pixel_count(), size_t(16 * 8));
    EXPECT_FLOAT_EQ(albedo.rgb[5], 0.25f);
    EXPECT_FLOAT_EQ(normal.rgb[3 * 7 + 1], 1.0f);
    const Image exr = s.image(true);
    size_t layers = 0;
    for (const Image::Channel& c : exr.extra)
        layers += c.name.rfind("albedo.", 0) == 0 || c.name.rfind("normal.", 0) == 0;
    EXPECT_EQ(layers, 6u);
}

TEST(AuxRender, AResultWithoutFirstHitsIsRejectedAndNothingMerges) {
    RenderSession s("r", small_spec(true), 0);
    const std::optional<SampleJob> job = start_and_lease(s);
    ASSERT_TRUE(job);
    SampleJobResult r = fake_result(*job);
    r.first_hits.clear();
    EXPECT_EQ(s.complete(1, "w", r).status, CompleteStatus::Rejected);
    EXPECT_EQ(s.merged().total_samples(), 0u);
}

// Off, nothing changes: jobs do not ask, no sums are kept, no layers written, and a
// result that brings first hits anyway is refused.
TEST(AuxRender, ARenderThatDoesNotAskKeepsNone) {
    RenderSession s("r", small_spec(false), 0);
    const std::optional<SampleJob> job = start_and_lease(s);
    ASSERT_TRUE(job);
    EXPECT_FALSE(job->aux);
    EXPECT_FALSE(s.aux().kept());
    SampleJob asked = *job;
    asked.aux = true;
    EXPECT_EQ(s.complete(1, "w", fake_result(asked)).status, CompleteStatus::Rejected);
    EXPECT_EQ(s.merged().total_samples(), 0u);
    EXPECT_EQ(s.image(true).extra.size(), 2u);  // sampleCount.Y and variance.Y only
}

TEST(AuxRender, CheckpointsKeepTheFirstHitSumsBitForBit) {
    RenderSession s("r", small_spec(true), 0);
    s.start();
    run(s, fake_result);
    const auto path = temp_file("cp.bin");
    Checkpoint cp{s.merged(), s.strategy().save_state(), 1, 0.5, {}, {}};
    cp.aux = s.aux();
    save_checkpoint(path, cp);
    std::optional<Checkpoint> back = load_checkpoint(path);
    ASSERT_TRUE(back);
    ASSERT_TRUE(back->aux.kept());
    for (size_t i = 0; i < s.merged().pixel_count(); ++i)
        ASSERT_EQ(0, std::memcmp(&back->aux.at(i), &s.aux().at(i), sizeof(FirstHitSums)));
    RenderSession resumed("r", small_spec(true), 0);
    resumed.restore(std::move(back->merged), back->strategy_state, 1, 0.5, {},
                    std::move(back->aux));
    EXPECT_FLOAT_EQ(resumed.aux().albedo(resumed.merged()).rgb[0], 0.25f);
    // A checkpoint without them cannot resume a render that keeps them.
    RenderSession other("r", small_spec(true), 0);
    EXPECT_THROW(other.restore(Accumulator(16, 8), nlohmann::json::object(), 1, 0.5),
                 std::runtime_error);
    std::filesystem::remove(path);
}

// A version 2 file (before issue 34: no first-hit byte) still loads, as a render
// without first-hit sums; a damaged one that claims them is refused.
TEST(AuxRender, AnOlderCheckpointLoadsWithoutFirstHitsAndADamagedOneIsRefused) {
    const auto path = temp_file("v2.bin");
    save_checkpoint(path, {Accumulator(4, 2), nlohmann::json::object(), 3, 1.0, {}, {}});
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    ASSERT_EQ(bytes[7], '3');
    ASSERT_EQ(bytes.back(), '\0');
    std::string v2 = bytes;
    v2[7] = '2';
    v2.pop_back();
    std::ofstream(path, std::ios::binary | std::ios::trunc) << v2;
    const std::optional<Checkpoint> old = load_checkpoint(path);
    ASSERT_TRUE(old);
    EXPECT_FALSE(old->aux.kept());
    EXPECT_EQ(old->rounds_done, 3u);
    // Claims first-hit sums and holds none: truncated. Holds sums its pixels' (zero)
    // samples cannot have added: refused as a worker's result would be.
    std::string claims = bytes;
    claims.back() = '\1';
    std::ofstream(path, std::ios::binary | std::ios::trunc) << claims;
    EXPECT_THROW(load_checkpoint(path), std::runtime_error);
    FirstHitSums bright;
    bright.albedo[0] = 1.0;
    for (int i = 0; i < 8; ++i)
        claims.append(reinterpret_cast<const char*>(&bright), sizeof bright);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << claims;
    EXPECT_THROW(load_checkpoint(path), std::exception);
    std::filesystem::remove(path);
}

}  // namespace
}  // namespace aliquot
