// PathTracer: unidirectional path tracing with next-event estimation and multiple
// importance sampling (power heuristic), Russian roulette from depth 5, as Mitsuba 3's
// `path` integrator does, so the two converge to the same image.
#pragma once

#include <cstdint>

#include "embree_scene.h"
#include "light_sampler.h"
#include "path_lanes.h"
#include "sampler.h"
#include "scene.h"

namespace aliquot {

struct Radiance {
    Vec3 value;
    uint32_t rays = 0;  // Embree queries (closest-hit and shadow), the deterministic cost
};

// A camera ray's first hit, what a denoiser reads beside the colour (FirstHitSums in
// sample_job.h): zero for a ray that leaves the scene.
struct FirstHit {
    Vec3 albedo{0.0f}, normal{0.0f};
};

class PathTracer {
public:
    static constexpr int kRussianRouletteDepth = 5;
    // Paths radiance_batch advances together: its lanes.
    static constexpr int kBatch = 64;

    explicit PathTracer(const Scene& scene);

    const Scene& scene() const { return scene_; }
    const EmbreeScene& embree() const { return embree_; }

    // Radiance arriving at `origin` from direction `dir` (unit length): a batch of one.
    Radiance radiance(const Vec3& origin, const Vec3& dir, SampleRng& rng) const;

    // The radiance of `count` camera rays from `origin`, kBatch paths traced together a
    // vertex at a time: camera rays, shadow rays and bounces as Embree packets of the
    // paths still going, and the diffuse vertices shaded together (path_lanes.h). As a
    // path ends, the next of the `count` takes its lane, so the lanes stay full while
    // paths are left. out[i] is what radiance() would give rngs[i]'s path up to
    // Embree's rounding, which may differ between its packet and single-ray kernels and
    // with a packet's other rays: callers make batches from what the render fixes
    // (trace_job.cpp). With `first_hits`, first_hits[i] is the first hit of path i, taken
    // from its camera ray as its lane is filled: the bounces' loop does nothing more.
    void radiance_batch(const Vec3& origin, const Vec3* dirs, int count, SampleRng* rngs,
                        Radiance* out, FirstHit* first_hits = nullptr) const;

private:
    const Material& material_at(const Hit& hit) const;
    // The first hit of a camera ray along `dir` that found `hit`.
    FirstHit first_hit(const Vec3& dir, const Hit& hit) const;
    // Path i arrives at vertex `hit`: adds the emission it finds there and returns the
    // surface's material, or nullptr if the path may not go on (its length is at most).
    const Material* arrive(PathLanes& paths, int i, const Hit& hit) const;
    // Marks path i's vertex as diffuse, for draw_diffuse_uniforms and shade_diffuse.
    void prepare_diffuse(PathLanes& paths, int i, const Material& mat) const;
    // Copies the emitting triangle each diffuse lane's u_select picks into its lane.
    void pick_lights(PathLanes& paths, int count, const int* active, int n_active) const;
    // Shades path i's mirror or dielectric vertex `hit`: the next direction and Russian
    // roulette. Whether the path goes on.
    bool scatter_specular(PathLanes& paths, int i, const Hit& hit,
                          const Material& mat) const;

    const Scene& scene_;
    EmbreeScene embree_;
    LightSampler lights_;
};

}  // namespace aliquot
