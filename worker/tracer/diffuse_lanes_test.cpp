#include "diffuse_lanes.h"

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
DiffuseLanes made_up_lanes(int count, uint32_t seed) {
    std::mt19937 gen(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    DiffuseLanes l;
    l.count = count;
    for (int j = 0; j < count; ++j) {
        l.path[j] = j;
        l.p.set(j, Vec3(u(gen) * 2 - 1, u(gen) * 2 - 1, u(gen) * 2 - 1));
        const Vec3 ng = unit(gen);
        l.ng.set(j, ng);
        l.n.set(j, u(gen) < 0.5f ? ng : -ng);
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

// A lane's outputs as bytes, to compare them bit for bit.
std::vector<float> outputs(const DiffuseLanes& l, int j) {
    std::vector<float> v;
    for (const DiffuseLanes::Vec3Lanes* a :
         {&l.shadow_origin, &l.shadow_dir, &l.shadow_L, &l.origin, &l.dir, &l.beta}) {
        const Vec3 x = a->get(j);
        v.insert(v.end(), {x.x, x.y, x.z});
    }
    v.insert(v.end(),
             {l.shadow_tmax[j], l.bsdf_pdf[j], float(l.shadow[j]), float(l.alive[j])});
    return v;
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * 4) == 0;
}

// The loop runs lanes side by side in SIMD registers, and a remainder one at a time: a
// lane shaded alone must give the same bits as in a full batch, or a sample's bytes
// would depend on its neighbours and on the instruction set.
TEST(DiffuseLanes, ALaneShadedAloneGivesTheSameBitsAsInABatch) {
    const DiffuseLanes batch_in = made_up_lanes(DiffuseLanes::kMax, 7);
    DiffuseLanes batch = batch_in;
    shade_diffuse(batch);
    for (int j = 0; j < DiffuseLanes::kMax; ++j) {
        DiffuseLanes one = made_up_lanes(1, 99);  // other values everywhere else
        // Lane j's inputs, moved to lane 0.
        one.p.set(0, batch_in.p.get(j));
        one.ng.set(0, batch_in.ng.get(j));
        one.n.set(0, batch_in.n.get(j));
        one.beta.set(0, batch_in.beta.get(j));
        one.reflectance.set(0, batch_in.reflectance.get(j));
        one.eta[0] = batch_in.eta[j];
        one.light_pdf[0] = batch_in.light_pdf[j];
        one.light_u1[0] = batch_in.light_u1[j];
        one.light_u2[0] = batch_in.light_u2[j];
        one.u1[0] = batch_in.u1[j];
        one.u2[0] = batch_in.u2[j];
        one.roulette[0] = batch_in.roulette[j];
        one.u_roulette[0] = batch_in.u_roulette[j];
        shade_diffuse(one);
        EXPECT_TRUE(same_bits(outputs(one, 0), outputs(batch, j))) << "lane " << j;
    }
}

TEST(DiffuseLanes, ShadowRaysGoTowardTheLightFromAboveTheSurface) {
    DiffuseLanes l = made_up_lanes(DiffuseLanes::kMax, 11);
    shade_diffuse(l);
    int shadows = 0, survivors = 0;
    for (int j = 0; j < l.count; ++j) {
        const Vec3 n = l.n.get(j), dir = l.dir.get(j);
        // The bounce leaves on the normal's side, unit length, with density cos/pi.
        EXPECT_NEAR(length(dir), 1.0f, 1e-5f);
        EXPECT_GE(dot(dir, n), -1e-6f);
        EXPECT_NEAR(l.bsdf_pdf[j], std::max(dot(dir, n), 0.0f) / float(M_PI), 1e-6f);
        if (!l.roulette[j]) {
            EXPECT_TRUE(l.alive[j]) << "no roulette before the fifth vertex";
            // Throughput times reflectance, to the bit.
            const DiffuseLanes in = made_up_lanes(DiffuseLanes::kMax, 11);
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
    EXPECT_LT(survivors, l.count);  // roulette ended some
}

}  // namespace
}  // namespace aliquot
