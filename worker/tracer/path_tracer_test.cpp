#include "path_tracer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "camera_model.h"
#include "scene_loader.h"
#include "test_scenes.h"

namespace aliquot {
namespace {

struct Estimate {
    double mean = 0, standard_error = 0;
};

// Mean luminance-free red channel over n samples of one camera direction, with its
// standard error measured from the same samples.
Estimate estimate(const PathTracer& tracer, const Vec3& origin, const Vec3& dir, int n) {
    double sum = 0, sum2 = 0;
    for (int k = 0; k < n; ++k) {
        SampleRng rng(99, 0, 0, uint64_t(k));
        const double v = tracer.radiance(origin, dir, rng).value.x;
        sum += v;
        sum2 += v * v;
    }
    const double mean = sum / n;
    const double var = std::max(0.0, sum2 / n - mean * mean);
    return {mean, std::sqrt(var / n)};
}

// White furnace: every surface emits 1 and reflects half, so with paths of at most d
// segments every camera ray sees sum_{i<d} 0.5^i, whatever the light sampling and MIS do.
TEST(PathTracer, WhiteFurnaceMatchesTheGeometricSeries) {
    for (int max_depth : {1, 2, 3, 8}) {
        Scene scene = load_scene("furnace");
        scene.max_depth = max_depth;
        const PathTracer tracer(scene);
        const double expected = (1.0 - std::pow(0.5, max_depth)) / (1.0 - 0.5);
        const Estimate e = estimate(tracer, scene.camera.position,
                                    normalize(Vec3(0.3f, -0.2f, -1.0f)), 40000);
        // Within 5 standard errors of the estimate itself, plus float rounding.
        EXPECT_NEAR(e.mean, expected, 5 * e.standard_error + 1e-4)
            << "max_depth " << max_depth;
    }
}

// Direct lighting at a point of a diffuse floor under a parallel square emitter, against
// the closed-form view factor from a differential area to a parallel rectangle (Howell,
// "A Catalog of Radiation Heat Transfer Configuration Factors", B-3): L = albedo * Le *
// F.
TEST(PathTracer, DirectLightingMatchesTheViewFactor) {
    const float half = 0.5f, height = 1.0f, albedo = 0.8f;
    Scene scene;
    scene.materials = {{"floor", Material::Kind::Diffuse, {albedo, albedo, albedo}, 1.5f},
                       {"black", Material::Kind::Diffuse, {0, 0, 0}, 1.5f}};
    TriangleMesh floor = test::horizontal_rectangle(100, 100, 0, true);
    floor.material = 0;
    TriangleMesh light = test::horizontal_rectangle(half, half, height, false);
    light.material = 1;
    light.emission = {1, 1, 1};
    scene.meshes = {floor, light};
    scene.max_depth = 2;  // emitters seen directly and direct lighting only
    const PathTracer tracer(scene);

    // The corner view factor for a rectangle a x b at distance c, times four quadrants.
    auto corner = [](double a, double b, double c) {
        const double A = a / c, B = b / c;
        return (A / std::sqrt(1 + A * A) * std::atan(B / std::sqrt(1 + A * A)) +
                B / std::sqrt(1 + B * B) * std::atan(A / std::sqrt(1 + B * B))) /
               (2 * std::numbers::pi);
    };
    const double expected = albedo * 4 * corner(half, half, height);

    const Vec3 origin{0, 0.5f, 3.0f};
    const Estimate e = estimate(tracer, origin, normalize(Vec3(0, 0, 0) - origin), 40000);
    EXPECT_NEAR(e.mean, expected, 5 * e.standard_error + 1e-4);
}

TEST(PathTracer, EmitterIsOneSided) {
    Scene scene;
    scene.materials = {{"black", Material::Kind::Diffuse, {0, 0, 0}, 1.5f}};
    TriangleMesh light = test::horizontal_rectangle(1, 1, 0, true);
    light.emission = {2, 2, 2};
    scene.meshes = {light};
    const PathTracer tracer(scene);
    SampleRng rng(1, 0, 0, 0);
    EXPECT_FLOAT_EQ(tracer.radiance({0, 1, 0}, {0, -1, 0}, rng).value.x, 2.0f);
    EXPECT_FLOAT_EQ(tracer.radiance({0, -1, 0}, {0, 1, 0}, rng).value.x, 0.0f);
}

TEST(PathTracer, CountsEveryEmbreeQueryAsARay) {
    const Scene scene = load_scene("cornell-box");
    const PathTracer tracer(scene);
    const CameraModel camera(scene.camera, 16, 16);
    SampleRng rng(1, 8, 8, 0);
    const Radiance r =
        tracer.radiance(camera.origin(), camera.direction(8.5f, 8.5f), rng);
    // At least the camera ray; at most one closest-hit and one shadow ray per vertex.
    EXPECT_GE(r.rays, 1u);
    EXPECT_LE(r.rays, uint32_t(2 * scene.max_depth));
}

// The batch traces the same paths as radiance() one by one: the same random draws in the
// same order, only Embree's packet kernels may round a hit differently. Every width of
// packet is exercised (batches of 1 to kBatch paths leave partial packets of all sizes),
// and batches of more paths than lanes, whose lanes the next paths take as paths end.
TEST(PathTracer, ABatchTracesThePathsRadianceTracesOneByOne) {
    for (const char* name : {"cornell-box", "cornell-caustics"}) {
        const Scene scene = load_scene(name);
        const PathTracer tracer(scene);
        const CameraModel camera(scene.camera, 32, 32);
        int paths = 0, same_rays = 0;
        double diff = 0, total = 0;
        for (int count : {1, 2, 5, 9, 16, 17, 40, PathTracer::kBatch, 65, 300}) {
            std::vector<SampleRng> batch_rngs, single_rngs;
            std::vector<Vec3> dirs(static_cast<size_t>(count), Vec3());
            for (int k = 0; k < count; ++k) {
                batch_rngs.emplace_back(5, uint32_t(count), 7, uint64_t(k));
                single_rngs.emplace_back(5, uint32_t(count), 7, uint64_t(k));
                const float px = 16.0f + batch_rngs.back().next_float();
                const float py = 12.0f + batch_rngs.back().next_float();
                single_rngs.back().next_float();
                single_rngs.back().next_float();
                dirs[size_t(k)] = camera.direction(px, py);
            }
            std::vector<Radiance> batch(static_cast<size_t>(count), Radiance{});
            tracer.radiance_batch(camera.origin(), dirs.data(), count, batch_rngs.data(),
                                  batch.data());
            for (int k = 0; k < count; ++k) {
                const Radiance one = tracer.radiance(camera.origin(), dirs[size_t(k)],
                                                     single_rngs[size_t(k)]);
                ++paths;
                same_rays += one.rays == batch[size_t(k)].rays;
                const Vec3 d = one.value - batch[size_t(k)].value;
                diff += std::fabs(d.x) + std::fabs(d.y) + std::fabs(d.z);
                total += std::fabs(one.value.x) + std::fabs(one.value.y) +
                         std::fabs(one.value.z);
            }
        }
        // Rounding can move a path across an edge now and then, never often.
        EXPECT_GE(same_rays, paths * 95 / 100) << name;
        EXPECT_LE(diff, 0.05 * total + 1e-6) << name;
    }
}

TEST(PathTracer, ANegativeCountIsRefused) {
    const Scene scene = load_scene("cornell-box");
    const PathTracer tracer(scene);
    EXPECT_THROW(tracer.radiance_batch({0, 1, 3}, nullptr, -1, nullptr, nullptr),
                 std::invalid_argument);
}

}  // namespace
}  // namespace aliquot
