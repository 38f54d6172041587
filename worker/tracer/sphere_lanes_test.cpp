#include "sphere_lanes.h"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>

#include "sphere_hit.h"

namespace aliquot {
namespace {

// The vectorised loop finds, bit for bit, what testing each ray against each sphere in
// turn finds, for every count of rays (full SIMD lanes and the remainder alike).
TEST(SphereLanes, NearestSpheresMatchTheOneRayTest) {
    const std::vector<Sphere> spheres = {
        {{0, 0, 0}, 1.0f, 0}, {{0.5f, 0, 2}, 0.5f, 0}, {{-3, 1, 0}, 2.0f, 0}};
    std::mt19937 gen(3);
    std::uniform_real_distribution<float> u(-4.0f, 4.0f);
    int hits = 0;
    for (int round = 0; round < 200; ++round) {
        const int count = 1 + round % RayLanes::kMax;
        RayLanes rays;
        const size_t n = static_cast<size_t>(count);
        std::vector<Vec3> o(n), d(n);
        std::vector<float> tmax(n);
        for (int i = 0; i < count; ++i) {
            o[size_t(i)] = Vec3(u(gen), u(gen), u(gen));
            // Aim near the first sphere's centre half the time; some rays start on it.
            const Vec3 target = i % 2 ? Vec3(u(gen), u(gen), u(gen)) * 0.2f
                                      : Vec3(u(gen), u(gen), u(gen));
            if (i % 5 == 0) o[size_t(i)] = normalize(o[size_t(i)]);  // on sphere 0
            d[size_t(i)] = target - o[size_t(i)];
            tmax[size_t(i)] = i % 3 ? std::numeric_limits<float>::infinity() : 0.7f;
            rays.set(i, o[size_t(i)], d[size_t(i)], tmax[size_t(i)]);
        }
        nearest_spheres(spheres, rays, count);
        for (int i = 0; i < count; ++i) {
            float t = tmax[size_t(i)];
            int which = -1;
            for (size_t s = 0; s < spheres.size(); ++s) {
                const float h = sphere_hit_t(o[size_t(i)], d[size_t(i)],
                                             spheres[s].center, spheres[s].radius, t);
                if (h < t) t = h, which = int(s);
            }
            EXPECT_EQ(rays.sphere[i], which) << "round " << round << " ray " << i;
            EXPECT_EQ(std::memcmp(&rays.t[i], &t, sizeof t), 0)
                << "round " << round << " ray " << i;
            hits += which >= 0;
        }
    }
    EXPECT_GT(hits, 300);  // most rays hit something, so the test compares hits
}

}  // namespace
}  // namespace aliquot
