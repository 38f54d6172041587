// PathTracer: unidirectional path tracing with next-event estimation and multiple
// importance sampling (power heuristic), Russian roulette from depth 5, as Mitsuba 3's
// `path` integrator does, so the two converge to the same image.
#pragma once

#include <cstdint>

#include "diffuse_lanes.h"
#include "embree_scene.h"
#include "light_sampler.h"
#include "sampler.h"
#include "scene.h"

namespace aliquot {

struct Radiance {
    Vec3 value;
    uint32_t rays = 0;  // Embree queries (closest-hit and shadow), the deterministic cost
};

// One path between Embree queries: its throughput, radiance so far, next ray, and the
// next-event shadow ray its last vertex asked for (what radiance() would keep in locals).
struct PathState {
    Vec3 L{0, 0, 0};
    Vec3 beta{1, 1, 1};
    Vec3 o, d;                   // the ray to the next vertex
    float eta = 1.0f;            // product of relative IORs crossed: Mitsuba's RR uses it
    float prev_bsdf_pdf = 0.0f;  // solid-angle pdf of the direction that led here
    bool prev_specular = true;   // camera rays and delta lobes take emission unweighted
    int depth = 0;
    uint32_t rays = 1;  // the camera ray, traced by the caller
    // The shadow ray of the last vertex: added to L as shadow_L if nothing blocks it.
    bool shadow = false;
    Vec3 shadow_origin, shadow_dir, shadow_L;
    float shadow_tmax = 0;
};

class PathTracer {
public:
    static constexpr int kRussianRouletteDepth = 5;
    // Paths radiance_batch advances together.
    static constexpr int kBatch = 64;

    explicit PathTracer(const Scene& scene);

    const Scene& scene() const { return scene_; }
    const EmbreeScene& embree() const { return embree_; }

    // Radiance arriving at `origin` from direction `dir` (unit length): a batch of one.
    Radiance radiance(const Vec3& origin, const Vec3& dir, SampleRng& rng) const;

    // The radiance of `count` (at most kBatch) camera rays from `origin`, traced together
    // a vertex at a time: camera rays, shadow rays and bounces as Embree packets of the
    // paths still going, in sample order, and the diffuse vertices shaded together
    // (diffuse_lanes.h). out[i] is what radiance() would give rngs[i]'s path up to
    // Embree's rounding, which may differ between its packet and single-ray kernels:
    // callers make batches from what the render fixes (trace_job.cpp).
    void radiance_batch(const Vec3& origin, const Vec3* dirs, int count, SampleRng* rngs,
                        Radiance* out) const;

private:
    const Material& material_at(const Hit& hit) const;
    // A path arrives at vertex `hit`: adds the emission it finds there and returns the
    // surface's material, or nullptr if the path may not go on (its length is at most).
    const Material* arrive(PathState& s, const Hit& hit) const;
    // Hands a diffuse vertex to `lanes`, drawing its random numbers from `rng` now, in
    // the order one-path shading would.
    void add_diffuse(DiffuseLanes& lanes, int path, const PathState& s, const Hit& hit,
                     const Material& mat, SampleRng& rng) const;
    // Shades a mirror or dielectric vertex: the next direction and Russian roulette.
    // Whether the path goes on, along (s.o, s.d).
    bool scatter_specular(PathState& s, const Hit& hit, const Material& mat,
                          SampleRng& rng) const;

    const Scene& scene_;
    EmbreeScene embree_;
    LightSampler lights_;
};

}  // namespace aliquot
