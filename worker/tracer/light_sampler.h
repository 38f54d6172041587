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

class LightSampler {
public:
    explicit LightSampler(const Scene& scene);

    bool empty() const { return triangles_.empty(); }
    LightSample sample(float u_select, float u1, float u2) const;
    // Area density of sampling any point of the given mesh (0 if it does not emit).
    float pdf_area(uint32_t mesh) const;

private:
    struct EmitterTriangle {
        Vec3 p0, e1, e2, normal, radiance;
        uint32_t mesh;
    };
    std::vector<EmitterTriangle> triangles_;
    std::vector<float> cdf_;  // inclusive, normalised to 1
    // pdf_area by mesh: weight / (area * total_weight) = luminance / total_weight.
    std::vector<float> pdf_by_mesh_;
};

}  // namespace aliquot
