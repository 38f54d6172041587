#include "embree_scene.h"

#include <gtest/gtest.h>

#include "test_scenes.h"

namespace aliquot {
namespace {

// Whether p (on the triangle's plane) lies inside triangle t of the mesh, edges included.
bool inside(const TriangleMesh& m, uint32_t t, const Vec3& p) {
    const Vec3 a = m.positions[m.triangles[t][0]], b = m.positions[m.triangles[t][1]],
               c = m.positions[m.triangles[t][2]];
    const Vec3 n = cross(b - a, c - a);
    constexpr float eps = -1e-5f;
    return dot(cross(b - a, p - a), n) >= eps && dot(cross(c - b, p - b), n) >= eps &&
           dot(cross(a - c, p - c), n) >= eps;
}

TEST(EmbreeScene, LoaderStyleTrianglePairsBecomeQuads) {
    EXPECT_TRUE(pairs_into_quads(test::horizontal_rectangle(1, 1, 0, false)));  // (0,1,2)(0,2,3)
    EXPECT_FALSE(pairs_into_quads(test::horizontal_rectangle(1, 1, 0, true)));  // (0,2,1)(0,3,2)
    TriangleMesh odd = test::horizontal_rectangle(1, 1, 0, false);
    odd.triangles.pop_back();
    EXPECT_FALSE(pairs_into_quads(odd));
    EXPECT_FALSE(pairs_into_quads(TriangleMesh{}));
}

// A skewed (non-rectangular, non-planar) quad traced as a quad must hit exactly where its two
// triangles are, report the triangle that was hit and that triangle's unit normal.
TEST(EmbreeScene, QuadHitsReportTheirTriangleAndItsNormal) {
    TriangleMesh m;
    m.positions = {{-1, 0, -1}, {1.2f, 0.1f, -0.8f}, {0.9f, -0.2f, 1.1f}, {-1.1f, 0.3f, 0.7f}};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    ASSERT_TRUE(pairs_into_quads(m));
    Scene scene;
    scene.materials.push_back({});
    scene.meshes.push_back(m);
    const EmbreeScene embree(scene);

    int hits[2] = {0, 0};
    for (int i = 0; i < 40; ++i) {
        for (int j = 0; j < 40; ++j) {
            const Vec3 origin(-1.2f + 2.4f * (i + 0.5f) / 40, 5, -1.2f + 2.4f * (j + 0.5f) / 40);
            Hit hit;
            if (!embree.intersect(origin, {0, -1, 0}, 100, hit)) continue;
            ASSERT_LT(hit.prim_id, 2u);
            ++hits[hit.prim_id];
            const Vec3 p = origin + Vec3(0, -1, 0) * hit.t;
            EXPECT_TRUE(inside(m, hit.prim_id, p)) << "hit at " << p.x << ", " << p.z;
            const Vec3 a = m.positions[m.triangles[hit.prim_id][0]];
            const Vec3 n = normalize(cross(m.positions[m.triangles[hit.prim_id][1]] - a,
                                           m.positions[m.triangles[hit.prim_id][2]] - a));
            EXPECT_NEAR(dot(hit.ng, n), 1.0f, 1e-6f);
        }
    }
    EXPECT_GT(hits[0], 100);
    EXPECT_GT(hits[1], 100);
}

TEST(EmbreeScene, TwoLevelBvhOnlyForScenesOfSmallMeshes) {
    Scene scene;
    scene.meshes.push_back(test::horizontal_rectangle(1, 1, 0, false));
    EXPECT_TRUE(two_level_bvh(scene));
    TriangleMesh big;
    big.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    big.triangles.assign(300, {0, 1, 2});
    scene.meshes.push_back(big);
    EXPECT_FALSE(two_level_bvh(scene));
}

}  // namespace
}  // namespace aliquot
