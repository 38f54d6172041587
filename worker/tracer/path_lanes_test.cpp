#include "path_lanes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

namespace aliquot {
namespace {

Vec3 unit(std::mt19937& gen) {
    std::normal_distribution<float> g;
    Vec3 v(g(gen), g(gen), g(gen));
    return v / length(v);
}

// Lanes of made-up vertices: a floor-like surface lit from above, some lanes past the
// roulette depth, some with the light behind them, one with no light at all.
PathLanes made_up_lanes(uint32_t seed) {
    std::mt19937 gen(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    PathLanes l;
    for (int j = 0; j < PathLanes::kMax; ++j) {
        l.diffuse[j] = j % 5 != 4;  // every fifth lane is not a diffuse vertex
        l.o.set(j, Vec3(u(gen) * 2 - 1, u(gen) * 2 - 1, u(gen) * 2 - 1));
        l.d.set(j, unit(gen));
        l.t[j] = u(gen);
        l.ng.set(j, unit(gen));
        l.prev_bsdf_pdf[j] = u(gen);
        l.beta.set(j, Vec3(u(gen), u(gen), u(gen)));
        l.reflectance.set(j, Vec3(u(gen), u(gen), u(gen)));
        l.eta[j] = u(gen) < 0.8f ? 1.0f : 1.5f;
        l.light_p0.set(j, Vec3(-0.25f, 0.99f, -0.25f));
        l.light_e1.set(j, Vec3(0.5f, 0, 0));
        l.light_e2.set(j, Vec3(0, 0, 0.5f));
        l.light_normal.set(j, Vec3(0, -1, 0));
        l.light_radiance.set(j, Vec3(17, 12, 4));
        l.light_pdf[j] = j == 3 ? 0.0f : 4.0f;
        l.light_u1[j] = u(gen);
        l.light_u2[j] = u(gen);
        l.u1[j] = u(gen);
        l.u2[j] = u(gen);
        l.roulette[j] = u(gen) < 0.5f;
        l.u_roulette[j] = u(gen);
    }
    return l;
}

// Lane j of `from` into lane k of `to`: every input of the shading.
void copy_lane(const PathLanes& from, int j, PathLanes& to, int k) {
    for (auto v :
         {&PathLanes::o, &PathLanes::d, &PathLanes::beta, &PathLanes::ng,
          &PathLanes::reflectance, &PathLanes::light_p0, &PathLanes::light_e1,
          &PathLanes::light_e2, &PathLanes::light_normal, &PathLanes::light_radiance})
        (to.*v).set(k, (from.*v).get(j));
    for (auto f : {&PathLanes::eta, &PathLanes::prev_bsdf_pdf, &PathLanes::t,
                   &PathLanes::light_pdf, &PathLanes::light_u1, &PathLanes::light_u2,
                   &PathLanes::u1, &PathLanes::u2, &PathLanes::u_roulette})
        (to.*f)[k] = (from.*f)[j];
    to.diffuse[k] = from.diffuse[j];
    to.roulette[k] = from.roulette[j];
}

// A lane's outputs, to compare them bit for bit.
std::vector<float> outputs(const PathLanes& l, int j) {
    std::vector<float> v;
    for (const PathLanes::Vec3Lanes* a :
         {&l.shadow_origin, &l.shadow_dir, &l.shadow_L, &l.o, &l.d, &l.beta}) {
        const Vec3 x = a->get(j);
        v.insert(v.end(), {x.x, x.y, x.z});
    }
    v.insert(v.end(), {l.shadow_tmax[j], l.prev_bsdf_pdf[j], float(l.shadow[j]),
                       float(l.alive[j])});
    return v;
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * 4) == 0;
}

// The loop runs lanes side by side in SIMD registers, and a remainder one at a time: a
// lane shaded alone must give the same bits as in a full batch, or a sample's bytes
// would depend on its neighbours and on the instruction set.
TEST(PathLanes, ALaneShadedAloneGivesTheSameBitsAsInABatch) {
    const PathLanes batch_in = made_up_lanes(7);
    PathLanes batch = batch_in;
    shade_diffuse(batch, PathLanes::kMax);
    for (int j = 0; j < PathLanes::kMax; ++j) {
        PathLanes one = made_up_lanes(99);  // other values everywhere else
        copy_lane(batch_in, j, one, 0);
        shade_diffuse(one, 1);
        EXPECT_TRUE(same_bits(outputs(one, 0), outputs(batch, j))) << "lane " << j;
    }
}

TEST(PathLanes, DiffuseLanesBounceAndCastShadowRaysOthersKeepTheirState) {
    const PathLanes in = made_up_lanes(11);
    PathLanes l = in;
    shade_diffuse(l, PathLanes::kMax);
    int shadows = 0, survivors = 0, diffuse = 0;
    for (int j = 0; j < PathLanes::kMax; ++j) {
        if (!in.diffuse[j]) {
            EXPECT_FALSE(l.shadow[j]);
            EXPECT_EQ(l.o.get(j), in.o.get(j));
            EXPECT_EQ(l.d.get(j), in.d.get(j));
            EXPECT_EQ(l.beta.get(j), in.beta.get(j));
            EXPECT_EQ(l.prev_bsdf_pdf[j], in.prev_bsdf_pdf[j]);
            continue;
        }
        ++diffuse;
        const Vec3 ng = in.ng.get(j), d_in = in.d.get(j);
        const Vec3 n = dot(d_in, ng) < 0 ? ng : -ng;
        const Vec3 dir = l.d.get(j);
        // The bounce leaves on the incoming side, unit length, with density cos/pi.
        EXPECT_NEAR(length(dir), 1.0f, 1e-5f);
        EXPECT_GE(dot(dir, n), -1e-6f);
        EXPECT_NEAR(l.prev_bsdf_pdf[j], std::max(dot(dir, n), 0.0f) / float(M_PI), 1e-6f);
        if (!in.roulette[j]) {
            EXPECT_TRUE(l.alive[j]) << "no roulette before the fifth vertex";
            // Throughput times reflectance, to the bit.
            EXPECT_EQ(l.beta.get(j), in.beta.get(j) * in.reflectance.get(j));
        }
        survivors += l.alive[j] != 0;
        if (!l.shadow[j]) continue;
        ++shadows;
        EXPECT_NE(j, 3) << "a lane with no light casts no shadow ray";
        const Vec3 to = l.shadow_dir.get(j);
        EXPECT_GT(dot(to, n), 0.0f);
        EXPECT_GT(to.y, 0.0f) << "the light is above every point";
        EXPECT_GT(l.shadow_tmax[j], 0.0f);
        const Vec3 L = l.shadow_L.get(j);
        EXPECT_TRUE(is_finite(L));
        EXPECT_GE(L.x, 0.0f);
    }
    EXPECT_GT(shadows, 10);
    EXPECT_LT(survivors, diffuse);  // roulette ended some
}

// The lanes pick the triangle LightSampler::pick picks for the same uniform, whatever
// the number of triangles the counting serves (1 to kFew).
TEST(PathLanes, FewLightsArePickedAsTheLightSamplerPicksThem) {
    std::mt19937 gen(5);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int n = 1; n <= int(LightSampler::kFew); ++n) {
        Scene scene;
        for (int k = 0; k < n; ++k) {  // triangles of different areas and radiances
            TriangleMesh mesh;
            const float x = float(3 * k), size = 1.0f + 0.5f * float(k % 3);
            mesh.positions = {{x, 0, 0}, {x + size, 0, 0}, {x, size, 0}};
            mesh.triangles = {{0, 1, 2}};
            mesh.emission = Vec3(float(1 + (k * 7) % 5));
            scene.meshes.push_back(mesh);
        }
        const LightSampler lights(scene);
        ASSERT_EQ(lights.emitters().size(), size_t(n));
        PathLanes l = made_up_lanes(unsigned(n));
        for (int i = 0; i < PathLanes::kMax; ++i) l.u_select[i] = u(gen);
        l.u_select[0] = 0.0f;
        l.u_select[1] = lights.cdf()[0];  // on an entry: the next triangle's
        pick_few_lights(l, PathLanes::kMax, lights.emitters().data(), lights.cdf().data(),
                        n);
        for (int i = 0; i < PathLanes::kMax; ++i) {
            const Emitter& e = lights.pick(l.u_select[i]);
            EXPECT_EQ(l.light_p0.get(i), e.p0) << n << " triangles, lane " << i;
            EXPECT_EQ(l.light_e1.get(i), e.e1);
            EXPECT_EQ(l.light_e2.get(i), e.e2);
            EXPECT_EQ(l.light_normal.get(i), e.normal);
            EXPECT_EQ(l.light_radiance.get(i), e.radiance);
            EXPECT_EQ(l.light_pdf[i], e.pdf_area);
        }
    }
}

}  // namespace
}  // namespace aliquot
