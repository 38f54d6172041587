// PathLanes: a batch of paths in structure-of-arrays form, one lane a path, so that the
// shading of their diffuse vertices (next-event estimation toward a point on the light,
// the cosine bounce, Russian roulette) runs as one loop the compiler vectorises: several
// paths a SIMD instruction instead of one path's chain of square roots and divisions at
// a time. A path's random numbers are drawn for it before the loop (in the order one-path
// shading would draw them), and the loop does the float operations shading.h and warp.h
// define, in their order, so a path's result does not depend on its lane or neighbours.
#pragma once

#include <cstdint>

#include "light_sampler.h"
#include "sampler.h"
#include "vec3.h"

namespace aliquot {

struct PathLanes {
    static constexpr int kMax = 64;

    // Three float arrays, one per component: what the loop loads and stores a lane of.
    struct Vec3Lanes {
        float x[kMax], y[kMax], z[kMax];
        Vec3 get(int i) const { return {x[i], y[i], z[i]}; }
        void set(int i, const Vec3& v) {
            x[i] = v.x;
            y[i] = v.y;
            z[i] = v.z;
        }
    };

    // The paths: the ray to the next vertex, radiance so far, throughput.
    Vec3Lanes o, d, L, beta;
    float eta[kMax];              // product of relative IORs crossed: roulette uses it
    float prev_bsdf_pdf[kMax];    // solid-angle pdf of the direction that led here
    int32_t prev_specular[kMax];  // camera rays and delta lobes take emission unweighted
    int32_t depth[kMax];
    uint32_t rays[kMax];  // Embree queries so far, camera ray included
    // The sample's random number generator (SampleRng's state, stepped in place).
    uint64_t rng_state[kMax], rng_inc[kMax];
    float next_float(int i) { return unit_float(pcg32_step(rng_state[i], rng_inc[i])); }

    // The vertex each path arrived at: distance along d and geometric normal.
    float t[kMax];
    Vec3Lanes ng;

    // In, where diffuse[i] != 0: the surface's reflectance, and whether roulette plays.
    int32_t diffuse[kMax];
    Vec3Lanes reflectance;
    int32_t roulette[kMax];
    // Drawn by draw_diffuse_uniforms: the uniform that picks an emitting triangle, the
    // two that place a point on it, the bounce's two, roulette's.
    float u_select[kMax], light_u1[kMax], light_u2[kMax];
    float u1[kMax], u2[kMax], u_roulette[kMax];
    // In: the emitting triangle picked for next-event estimation (pdf 0: none, and no
    // shadow ray).
    Vec3Lanes light_p0, light_e1, light_e2, light_normal, light_radiance;
    float light_pdf[kMax];

    // Out, where diffuse[i] != 0: the shadow ray (where shadow[i] != 0) and what it adds
    // if nothing blocks it; whether the path goes on. The shading also moves o and d to
    // the next ray and updates beta and prev_bsdf_pdf; other lanes keep theirs.
    int32_t shadow[kMax];
    Vec3Lanes shadow_origin, shadow_dir, shadow_L;
    float shadow_tmax[kMax];
    int32_t alive[kMax];
};

// Draws the random numbers of the diffuse vertices among lanes [0, count) from their
// generators, in the order one-path shading draws them: a light pick and point (if the
// scene has a light), the bounce, roulette's where it plays.
void draw_diffuse_uniforms(PathLanes& lanes, int count, bool light);

// Copies into lanes [0, count) the emitting triangle each lane's u_select picks from
// `emitters` (n of them, at most LightSampler::kFew) by its cdf, as LightSampler::pick.
void pick_few_lights(PathLanes& lanes, int count, const Emitter* emitters,
                     const float* cdf, int n);

// Shades the diffuse vertices among lanes [0, count).
void shade_diffuse(PathLanes& lanes, int count);

}  // namespace aliquot
