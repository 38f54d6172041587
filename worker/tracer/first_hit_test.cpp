// The first-hit albedo and normal a job returns when it is asked for them (issue 34):
// what the coordinator hands a denoiser beside the colour.
#include <gtest/gtest.h>

#include <cstring>
#include <initializer_list>

#include "scene_loader.h"
#include "trace_job.h"

namespace aliquot {
namespace {

// A camera at z = 3 looking down -z at a diffuse rectangle ([-1, 1]^2 at z = 0) that
// fills its view: every camera ray hits the wall. The scene's light is far to the side,
// out of view; `shapes` adds more.
Scene wall_scene(const char* target, const std::string& shapes = "") {
    return parse_scene(std::string(R"({
        "camera": {"position": [0, 0, 3], "target": )") +
                           target + R"(, "up": [0, 1, 0], "fov": 20},
        "materials": {"wall": {"type": "diffuse", "reflectance": [0.2, 0.4, 0.6]}},
        "shapes": [{"type": "rectangle", "material": "wall"},
                   {"type": "rectangle", "material": "wall", "emission": [1, 1, 1],
                    "transform": {"translate": [50, 0, 0]}})" +
                           shapes + "]}",
                       "scenes/wall.json", ".");
}

// Each pixel (x, y) with x and y in `at` of an 8x8 job over the whole image has the mean
// first-hit albedo `expected`.
void expect_mean_albedo(const SampleJobResult& r, std::initializer_list<uint32_t> at,
                        const Vec3& expected) {
    for (uint32_t y : at)
        for (uint32_t x : at) {
            const FirstHitSums& f = r.first_hits[y * 8 + x];
            const double n = double(r.pixels[y * 8 + x].samples);
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(f.albedo[c] / n, expected[c], 1e-6)
                    << x << "," << y << " " << c;
        }
}

SampleJob job_of(const PixelRect& rect, uint32_t spp, bool aux) {
    SampleJob job;
    job.rect = rect;
    job.counts.assign(rect.size(), spp);
    for (size_t i = 0; i < rect.size(); ++i) job.counts[i] = uint32_t(spp + i % 3);
    job.first_sample.assign(rect.size(), 0);
    job.aux = aux;
    return job;
}

TEST(FirstHit, ADiffuseWallsMeanAlbedoIsItsReflectanceAndItsNormalFacesTheCamera) {
    const Scene scene = wall_scene("[0, 0, 0]");
    const PathTracer tracer(scene);
    const SampleJobResult r =
        trace_sample_job(tracer, {8, 8, 3}, job_of({0, 0, 8, 8}, 4, true), 1);
    ASSERT_EQ(r.first_hits.size(), r.pixels.size());
    const float reflectance[3] = {0.2f, 0.4f, 0.6f};
    for (size_t i = 0; i < r.pixels.size(); ++i) {
        const double n = double(r.pixels[i].samples);
        ASSERT_GT(n, 0);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(r.first_hits[i].albedo[c] / n, reflectance[c], 1e-7);
        EXPECT_NEAR(r.first_hits[i].normal[0] / n, 0.0, 1e-6);
        EXPECT_NEAR(r.first_hits[i].normal[1] / n, 0.0, 1e-6);
        EXPECT_NEAR(r.first_hits[i].normal[2] / n, 1.0, 1e-6);
    }
}

// A light (a quarter-size rectangle at z = 0.5, the wall's material, emission 4, 2, 1)
// in the middle of the view: its pixels record its emission's colour normalised to its
// largest component, so the denoiser sees its edge; the corners, beside it, the wall's
// reflectance. Before, the light's pixels had the wall's reflectance too.
TEST(FirstHit, ALightRecordsItsNormalisedEmissionAndTheWallBesideItItsReflectance) {
    const Scene scene =
        wall_scene("[0, 0, 0]", R"(, {"type": "rectangle", "material": "wall",
        "emission": [4, 2, 1], "transform": {"translate": [0, 0, 0.5], "scale": 0.25}})");
    const PathTracer tracer(scene);
    const SampleJobResult r =
        trace_sample_job(tracer, {8, 8, 3}, job_of({0, 0, 8, 8}, 4, true), 1);
    ASSERT_EQ(r.first_hits.size(), r.pixels.size());
    expect_mean_albedo(r, {3, 4}, Vec3(1.0f, 0.5f, 0.25f));
    expect_mean_albedo(r, {0, 7}, Vec3(0.2f, 0.4f, 0.6f));
}

// A light seen from behind does not emit (arrive adds emission from the front only): its
// back records its surface's reflectance, as any wall.
TEST(FirstHit, ALightsBackRecordsItsReflectance) {
    const Scene scene =
        wall_scene("[0, 0, 0]", R"(, {"type": "rectangle", "material": "wall",
        "emission": [4, 2, 1],
        "transform": {"translate": [0, 0, 0.5], "rotate": ["y", 180], "scale": 0.25}})");
    const PathTracer tracer(scene);
    const SampleJobResult r =
        trace_sample_job(tracer, {8, 8, 3}, job_of({0, 0, 8, 8}, 4, true), 1);
    ASSERT_EQ(r.first_hits.size(), r.pixels.size());
    expect_mean_albedo(r, {3, 4}, Vec3(0.2f, 0.4f, 0.6f));
}

TEST(FirstHit, ARayThatLeavesTheSceneAddsZero) {
    const Scene scene = wall_scene("[0, 0, 6]");  // looking away from the wall
    const PathTracer tracer(scene);
    const SampleJobResult r =
        trace_sample_job(tracer, {8, 8, 3}, job_of({0, 0, 8, 8}, 2, true), 1);
    ASSERT_EQ(r.first_hits.size(), r.pixels.size());
    for (const FirstHitSums& f : r.first_hits) EXPECT_EQ(f, FirstHitSums{});
}

// Without `aux` nothing is returned beside the colour, and the colour is the same bits
// with or without: the first hits are read, never drawn from a path's random numbers.
TEST(FirstHit, OnlyAJobThatAsksGetsThemAndTheColourDoesNotChange) {
    const Scene scene = load_scene("cornell-box");
    const PathTracer tracer(scene);
    const RenderGeometry geometry{16, 16, 9};
    const SampleJobResult without =
        trace_sample_job(tracer, geometry, job_of({0, 0, 16, 16}, 3, false), 1);
    const SampleJobResult with =
        trace_sample_job(tracer, geometry, job_of({0, 0, 16, 16}, 3, true), 1);
    EXPECT_TRUE(without.first_hits.empty());
    ASSERT_EQ(with.first_hits.size(), with.pixels.size());
    for (size_t i = 0; i < with.pixels.size(); ++i)
        ASSERT_EQ(0, std::memcmp(&with.pixels[i], &without.pixels[i], sizeof(PixelSums)));
}

// Cut into cell-aligned jobs and traced with 1 or 2 threads, every pixel's first-hit sums
// are the whole job's bits.
TEST(FirstHit, SumsDoNotDependOnJobCutsOrThreads) {
    const Scene scene = load_scene("cornell-box");
    const PathTracer tracer(scene);
    const uint32_t w = 24, h = 19;
    const RenderGeometry geometry{w, h, 4};
    const SampleJobResult whole =
        trace_sample_job(tracer, geometry, job_of({0, 0, w, h}, 2, true), 1);
    for (int threads : {1, 2})
        for (uint32_t y0 = 0; y0 < h; y0 += 8)
            for (uint32_t x0 = 0; x0 < w; x0 += 16) {
                const PixelRect rect{x0, y0, std::min(16u, w - x0), std::min(8u, h - y0)};
                SampleJob part = job_of(rect, 2, true);
                for (uint32_t y = 0; y < rect.height; ++y)
                    for (uint32_t x = 0; x < rect.width; ++x)
                        part.counts[y * rect.width + x] =
                            uint32_t(2 + ((y0 + y) * w + x0 + x) % 3);
                const SampleJobResult cut =
                    trace_sample_job(tracer, geometry, part, threads);
                for (uint32_t y = 0; y < rect.height; ++y)
                    for (uint32_t x = 0; x < rect.width; ++x)
                        ASSERT_EQ(0, std::memcmp(&cut.first_hits[y * rect.width + x],
                                                 &whole.first_hits[(y0 + y) * w + x0 + x],
                                                 sizeof(FirstHitSums)))
                            << "pixel " << x0 + x << "," << y0 + y;
            }
}

}  // namespace
}  // namespace aliquot
