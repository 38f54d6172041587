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
    // The triangle sample() would take for u_select: the batched shading picks it per
    // path, then places the points of many paths in one vectorised loop.
    const Emitter& pick(float u_select) const;
    // Area density of sampling any point of the given mesh (0 if it does not emit).
    float pdf_area(uint32_t mesh) const;

private:
    std::vector<Emitter> triangles_;
    std::vector<float> cdf_;  // inclusive, normalised to 1
    // pdf_area by mesh: weight / (area * total_weight) = luminance / total_weight.
    std::vector<float> pdf_by_mesh_;
};

}  // namespace aliquot
