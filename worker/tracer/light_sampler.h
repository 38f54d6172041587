// LightSampler: picks a point on the scene's emitters, each emitting triangle with
// probability proportional to its area times its radiance's luminance (for a single
// emitter: uniform by area, as Mitsuba samples one area light).
#pragma once

#include <cstdint>
#include <vector>

#include "scene.h"

namespace aliquot {

struct LightSample {
    Vec3 position;
    Vec3 normal;  // unit, the emitting side
    Vec3 radiance;
    float pdf_area;  // with respect to area on the emitter
};

// One emitting triangle: a corner, its two edges, its unit normal (the emitting side),
// its radiance, and the area density of sampling any point of it.
struct Emitter {
    Vec3 p0, e1, e2, normal, radiance;
    float pdf_area;
};

class LightSampler {
public:
    explicit LightSampler(const Scene& scene);

    bool empty() const { return triangles_.empty(); }
    LightSample sample(float u_select, float u1, float u2) const;
    // The triangle sample() would take for u_select. Inline and, for kFew triangles or
    // fewer (every built-in scene has two), without branches: which triangle a uniform
    // picks is a coin flip a branch predictor always loses. (The batched tracer counts
    // the same way over many paths at once: pick_few_lights, path_lanes.h.)
    static constexpr size_t kFew = 8;
    const Emitter& pick(float u_select) const {
        if (cdf_.size() > kFew) return pick_by_search(u_select);
        // The first entry above u_select, as upper_bound finds it: the count of entries
        // at most u_select (the cdf is sorted), the last one at most.
        size_t i = 0;
        for (size_t k = 0; k + 1 < cdf_.size(); ++k) i += cdf_[k] <= u_select;
        return triangles_[i];
    }
    const std::vector<Emitter>& emitters() const { return triangles_; }
    const std::vector<float>& cdf() const { return cdf_; }  // inclusive, normalised
    // Area density of sampling any point of the given mesh (0 if it does not emit).
    float pdf_area(uint32_t mesh) const;

private:
    const Emitter& pick_by_search(float u_select) const;

    std::vector<Emitter> triangles_;
    std::vector<float> cdf_;  // inclusive, normalised to 1
    // pdf_area by mesh: weight / (area * total_weight) = luminance / total_weight.
    std::vector<float> pdf_by_mesh_;
};

}  // namespace aliquot
