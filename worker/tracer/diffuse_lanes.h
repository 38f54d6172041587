// DiffuseLanes: the diffuse vertices of a batch of paths in structure-of-arrays form, so
// that their shading (next-event estimation toward a point on the light, the cosine
// bounce, Russian roulette) runs as one loop the compiler vectorises: several paths a
// SIMD instruction instead of one path's chain of square roots and divisions at a time.
// A path's random numbers are drawn for it before the loop (in the order one-path
// shading draws them), and the loop does the float operations shading.h and warp.h
// define in their order, so a path's result does not depend on its lane or neighbours.
#pragma once

#include <cstdint>

#include "vec3.h"

namespace aliquot {

struct DiffuseLanes {
    static constexpr int kMax = 64;

    // Three float arrays, one per component: what the loop loads and stores a lane of.
    struct Vec3Lanes {
        float x[kMax], y[kMax], z[kMax];
        Vec3 get(int j) const { return {x[j], y[j], z[j]}; }
        void set(int j, const Vec3& v) {
            x[j] = v.x;
            y[j] = v.y;
            z[j] = v.z;
        }
    };

    int count = 0;
    int path[kMax];  // the caller's index of the lane's path

    // In: the vertex, its geometric normal, the normal facing the incoming ray, the
    // path's throughput and the surface's reflectance.
    Vec3Lanes p, ng, n, beta, reflectance;
    float eta[kMax];  // product of relative IORs crossed (roulette uses it)
    // In: the emitting triangle picked for next-event estimation (pdf 0: none, no shadow
    // ray) and the two uniforms that place a point on it.
    Vec3Lanes light_p0, light_e1, light_e2, light_normal, light_radiance;
    float light_pdf[kMax], light_u1[kMax], light_u2[kMax];
    // In: the bounce's two uniforms; roulette's uniform, used where roulette[j] != 0.
    float u1[kMax], u2[kMax], u_roulette[kMax];
    int32_t roulette[kMax];

    // Out: the shadow ray (where shadow[j] != 0) and what it adds if nothing blocks it.
    int32_t shadow[kMax];
    Vec3Lanes shadow_origin, shadow_dir, shadow_L;
    float shadow_tmax[kMax];
    // Out: the next ray, the bounce's solid-angle pdf, the throughput after it (in beta)
    // and whether the path goes on.
    Vec3Lanes origin, dir;
    float bsdf_pdf[kMax];
    int32_t alive[kMax];
};

// Shades lanes [0, count): fills the outputs from the inputs.
void shade_diffuse(DiffuseLanes& lanes);

}  // namespace aliquot
