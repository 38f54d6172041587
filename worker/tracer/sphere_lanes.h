// Rays in structure-of-arrays form tested against every sphere of a scene in one loop a
// sphere that the compiler vectorises: a packet's rays pass through the spheres together
// instead of each one alone (alone, the square roots and divisions of the test were a
// fifth of a cornell-caustics render).
#pragma once

#include <cstdint>
#include <vector>

#include "scene.h"

namespace aliquot {

struct RayLanes {
    static constexpr int kMax = 16;  // EmbreeScene::kPacket
    float ox[kMax], oy[kMax], oz[kMax], dx[kMax], dy[kMax], dz[kMax];
    // In: how far the ray looks (its nearest hit so far, or the query's bound). Out: the
    // nearest sphere hit below that, if there is one.
    float t[kMax];
    int32_t sphere[kMax];  // out: the index of that sphere, or -1

    void set(int i, const Vec3& origin, const Vec3& dir, float tmax) {
        ox[i] = origin.x, oy[i] = origin.y, oz[i] = origin.z;
        dx[i] = dir.x, dy[i] = dir.y, dz[i] = dir.z;
        t[i] = tmax;
    }
    Vec3 origin(int i) const { return {ox[i], oy[i], oz[i]}; }
    Vec3 dir(int i) const { return {dx[i], dy[i], dz[i]}; }
};

// For rays [0, count): the nearest sphere each hits nearer than its t, spheres taken in
// order and a later one only if strictly nearer, as sphere_hit_t one ray at a time.
void nearest_spheres(const std::vector<Sphere>& spheres, RayLanes& rays, int count);

}  // namespace aliquot
