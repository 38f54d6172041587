#include "embree_scene.h"

#include <gtest/gtest.h>

#include "camera_model.h"
#include "scene_loader.h"
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
    EXPECT_TRUE(
        pairs_into_quads(test::horizontal_rectangle(1, 1, 0, false)));  // (0,1,2)(0,2,3)
    EXPECT_FALSE(
        pairs_into_quads(test::horizontal_rectangle(1, 1, 0, true)));  // (0,2,1)(0,3,2)
    TriangleMesh odd = test::horizontal_rectangle(1, 1, 0, false);
    odd.triangles.pop_back();
    EXPECT_FALSE(pairs_into_quads(odd));
    EXPECT_FALSE(pairs_into_quads(TriangleMesh{}));
}

// A skewed (non-rectangular, non-planar) quad traced as a quad must hit exactly where its
// two triangles are, report the triangle that was hit and that triangle's unit normal.
TEST(EmbreeScene, QuadHitsReportTheirTriangleAndItsNormal) {
    TriangleMesh m;
    m.positions = {
        {-1, 0, -1}, {1.2f, 0.1f, -0.8f}, {0.9f, -0.2f, 1.1f}, {-1.1f, 0.3f, 0.7f}};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    ASSERT_TRUE(pairs_into_quads(m));
    Scene scene;
    scene.materials.push_back({});
    scene.meshes.push_back(m);
    const EmbreeScene embree(scene);

    int hits[2] = {0, 0};
    for (int i = 0; i < 40; ++i) {
        for (int j = 0; j < 40; ++j) {
            const Vec3 origin(-1.2f + 2.4f * (i + 0.5f) / 40, 5,
                              -1.2f + 2.4f * (j + 0.5f) / 40);
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

// Camera rays traced as packets find what single rays find. The packet kernel may round
// differently, so hits are compared to a tolerance, and a ray grazing an edge may pick
// the neighbouring primitive.
TEST(EmbreeScene, PacketHitsAgreeWithSingleRayHits) {
    const Scene scene = load_scene("cornell-box");
    const EmbreeScene embree(scene);
    const CameraModel camera(scene.camera, 64, 64);
    size_t rays = 0, hits = 0, other_primitive = 0;
    for (uint32_t y = 0; y < 64; ++y) {
        for (uint32_t x = 0; x < 64; ++x) {
            const int count =
                1 + int((x + 3 * y) % EmbreeScene::kPacket);  // partial packets
            Vec3 dirs[EmbreeScene::kPacket];
            for (int j = 0; j < count; ++j)
                dirs[j] =
                    camera.direction(x + (j % 4 + 0.5f) / 4, y + (j / 4 + 0.5f) / 4);
            Hit packet[EmbreeScene::kPacket];
            bool found[EmbreeScene::kPacket];
            embree.intersect_packet(camera.origin(), dirs, count, packet, found);
            for (int j = 0; j < count; ++j) {
                ++rays;
                Hit single;
                const bool single_found =
                    embree.intersect(camera.origin(), dirs[j], 1e30f, single);
                ASSERT_EQ(found[j], single_found);
                if (!found[j]) continue;
                ++hits;
                EXPECT_NEAR(packet[j].t, single.t, 1e-5f * single.t);
                if (packet[j].geom_id != single.geom_id ||
                    packet[j].prim_id != single.prim_id)
                    ++other_primitive;
            }
        }
    }
    EXPECT_GT(hits, rays * 9 / 10);
    EXPECT_LE(other_primitive, rays / 1000);
}

// A scene of more spheres than our own test takes (a 4 MB scene can hold tens of
// thousands, and every ray would test each) has them traced by Embree's BVH: single rays,
// packets and shadow rays find the sphere they aim at, at its analytic distance, with the
// outward normal and the sphere's index, as for a few spheres.
TEST(EmbreeScene, ManySpheresAreTracedByEmbreesBvh) {
    Scene scene;
    const int count = int(EmbreeScene::kOwnSpheres) * 4;
    for (int k = 0; k < count; ++k)
        scene.spheres.push_back({Vec3(float(3 * k), 0, 0), 1.0f, 0});
    const EmbreeScene embree(scene);
    ASSERT_EQ(embree.sphere_geometry(), 0u);  // one past no meshes
    for (int k : {0, 17, count - 1}) {
        const Vec3 origin(float(3 * k), 0, 5), dir(0, 0, -1);
        Hit hit;
        ASSERT_TRUE(embree.intersect(origin, dir, 1e30f, hit)) << k;
        EXPECT_EQ(hit.geom_id, embree.sphere_geometry());
        EXPECT_EQ(hit.prim_id, uint32_t(k));
        EXPECT_NEAR(hit.t, 4.0f, 1e-4f);
        EXPECT_NEAR(dot(hit.ng, -dir), 1.0f, 1e-4f);
        EXPECT_TRUE(embree.occluded(origin, dir, 1e30f));
        EXPECT_FALSE(embree.occluded(origin, dir, 3.9f));
    }
    Vec3 origins[EmbreeScene::kPacket], dirs[EmbreeScene::kPacket];
    float tmax[EmbreeScene::kPacket];
    for (int j = 0; j < EmbreeScene::kPacket; ++j) {
        origins[j] = Vec3(float(3 * (2 * j)), 0.5f, 5);  // sphere 2j, off its centre
        dirs[j] = Vec3(0, 0, -1);
        tmax[j] = j % 2 ? 1e30f : 3.0f;
    }
    Hit hits[EmbreeScene::kPacket];
    bool found[EmbreeScene::kPacket], blocked[EmbreeScene::kPacket];
    embree.intersect_packet(origins, dirs, EmbreeScene::kPacket, hits, found);
    embree.occluded_packet(origins, dirs, tmax, EmbreeScene::kPacket, blocked);
    for (int j = 0; j < EmbreeScene::kPacket; ++j) {
        ASSERT_TRUE(found[j]) << j;
        EXPECT_EQ(hits[j].prim_id, uint32_t(2 * j));
        EXPECT_NEAR(hits[j].t, 5.0f - std::sqrt(0.75f), 1e-4f);
        EXPECT_NEAR(length(hits[j].ng), 1.0f, 1e-5f);
        EXPECT_EQ(blocked[j], j % 2 == 1) << j;
    }
}

// Spheres are tested in our own code beside Embree's meshes (sphere_hit.h): single rays,
// packets and shadow rays see them, nearer than the wall behind, with outward normals.
TEST(EmbreeScene, SpheresAreHitInFrontOfTheMeshesBehindThem) {
    const Scene scene = load_scene("cornell-caustics");
    ASSERT_EQ(scene.spheres.size(), 2u);
    const EmbreeScene embree(scene);
    const Sphere& glass = scene.spheres[0];
    const Vec3 origin(glass.center.x, glass.center.y, 3.0f);
    const Vec3 dir = normalize(glass.center - origin);
    Hit hit;
    ASSERT_TRUE(embree.intersect(origin, dir, 1e30f, hit));
    EXPECT_EQ(hit.geom_id, embree.sphere_geometry());
    EXPECT_EQ(hit.prim_id, 0u);
    EXPECT_NEAR(hit.t, length(glass.center - origin) - glass.radius, 1e-5f);
    EXPECT_NEAR(dot(hit.ng, -dir), 1.0f, 1e-5f);  // outward, facing the ray
    // The wall behind the sphere is what a ray bounded before the sphere does not see.
    EXPECT_FALSE(embree.intersect(origin, dir, hit.t * 0.99f, hit));
    EXPECT_TRUE(embree.occluded(origin, dir, 1e30f));
    EXPECT_FALSE(embree.occluded(origin, dir, 0.5f));

    Vec3 origins[EmbreeScene::kPacket], dirs[EmbreeScene::kPacket];
    float tmax[EmbreeScene::kPacket];
    for (int j = 0; j < EmbreeScene::kPacket; ++j) {
        origins[j] = origin;
        dirs[j] = normalize(glass.center + Vec3(0.05f * float(j - 8), 0, 0) - origin);
        tmax[j] = (j % 2) ? 1e30f : 0.5f;
    }
    Hit hits[EmbreeScene::kPacket];
    bool found[EmbreeScene::kPacket], blocked[EmbreeScene::kPacket];
    embree.intersect_packet(origins, dirs, EmbreeScene::kPacket, hits, found);
    embree.occluded_packet(origins, dirs, tmax, EmbreeScene::kPacket, blocked);
    for (int j = 0; j < EmbreeScene::kPacket; ++j) {
        Hit single;
        ASSERT_TRUE(found[j]);
        ASSERT_TRUE(embree.intersect(origins[j], dirs[j], 1e30f, single));
        EXPECT_EQ(hits[j].geom_id, single.geom_id) << j;
        EXPECT_NEAR(hits[j].t, single.t, 1e-5f * single.t) << j;
        EXPECT_EQ(blocked[j], embree.occluded(origins[j], dirs[j], tmax[j])) << j;
    }
}

TEST(EmbreeScene, PacketRejectsMoreRaysThanItHolds) {
    const Scene scene = load_scene("cornell-box");
    const EmbreeScene embree(scene);
    Vec3 dirs[EmbreeScene::kPacket + 1];
    Hit hits[EmbreeScene::kPacket + 1];
    bool found[EmbreeScene::kPacket + 1];
    EXPECT_THROW(
        embree.intersect_packet({0, 1, 3}, dirs, EmbreeScene::kPacket + 1, hits, found),
        std::invalid_argument);
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
