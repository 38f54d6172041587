#include "light_sampler.h"

#include <gtest/gtest.h>

#include <vector>

namespace aliquot {
namespace {

// A strip of `n` unit right triangles along x, triangle k emitting k + 1 (so weights
// 1, 2, ..., n), each its own mesh.
Scene strip_of_emitters(int n) {
    Scene scene;
    for (int k = 0; k < n; ++k) {
        TriangleMesh mesh;
        const float x = float(2 * k);
        mesh.positions = {{x, 0, 0}, {x + 1, 0, 0}, {x, 1, 0}};
        mesh.triangles = {{0, 1, 2}};
        mesh.emission = Vec3(float(k + 1));
        scene.meshes.push_back(mesh);
    }
    return scene;
}

// pick() takes a triangle with probability proportional to its weight, whether it
// counts the cdf (a few triangles) or searches it (many): triangle k owns the u in
// [W(k-1), W(k)) of the running weights W.
TEST(LightSampler, PickTakesTheTriangleWhoseCdfIntervalHoldsU) {
    for (int n : {1, 2, 3, 8, 9, 40}) {
        const LightSampler lights(strip_of_emitters(n));
        const double total = n * (n + 1) / 2.0;
        for (int s = 0; s < 4000; ++s) {
            const float u = (float(s) + 0.5f) / 4000.0f;
            const Emitter& e = lights.pick(u);
            const int k = int(e.p0.x) / 2;
            const double below = k * (k + 1) / 2.0 / total;
            const double upto = (k + 1) * (k + 2) / 2.0 / total;
            EXPECT_GE(u, below - 1e-6) << n << " triangles, u " << u;
            EXPECT_LT(u, upto + 1e-6) << n << " triangles, u " << u;
            // The area density: weight / (area * total weight) = (k + 1) / (total / 2),
            // each triangle's area being 1/2.
            EXPECT_NEAR(e.pdf_area, float((k + 1) / (0.5 * total)), 1e-5);
        }
    }
}

TEST(LightSampler, SampleIsAPointOnThePickedTriangleFacingItsNormal) {
    const LightSampler lights(strip_of_emitters(3));
    const LightSample ls = lights.sample(0.99f, 0.25f, 0.5f);
    EXPECT_GE(ls.position.x, 4.0f);  // the last triangle, weight 3 of 6
    EXPECT_LE(ls.position.x + ls.position.y, 5.0f + 1e-6f);
    EXPECT_EQ(ls.normal, Vec3(0, 0, 1));
    EXPECT_EQ(ls.radiance, Vec3(3.0f));
}

}  // namespace
}  // namespace aliquot
