// PathTracer: unidirectional path tracing with next-event estimation and multiple
// importance sampling (power heuristic), Russian roulette from depth 5, as Mitsuba 3's
// `path` integrator does, so the two converge to the same image.
#pragma once

#include <cstdint>

#include "embree_scene.h"
#include "light_sampler.h"
#include "sampler.h"
#include "scene.h"

namespace aliquot {

struct Radiance {
    Vec3 value;
    uint32_t rays = 0;  // Embree queries (closest-hit and shadow), the deterministic cost
};

class PathTracer {
public:
    static constexpr int kRussianRouletteDepth = 5;

    explicit PathTracer(const Scene& scene);

    const Scene& scene() const { return scene_; }
    const EmbreeScene& embree() const { return embree_; }

    // Radiance arriving at `origin` from direction `dir` (unit length).
    Radiance radiance(const Vec3& origin, const Vec3& dir, SampleRng& rng) const;
    // The same, with the first hit already traced (nullptr: the ray hit nothing), as
    // camera rays are, a packet at a time. It counts as the path's first ray.
    Radiance radiance(const Vec3& origin, const Vec3& dir, const Hit* first,
                      SampleRng& rng) const;

private:
    const Material& material_at(const Hit& hit) const;

    const Scene& scene_;
    EmbreeScene embree_;
    LightSampler lights_;
};

}  // namespace aliquot
