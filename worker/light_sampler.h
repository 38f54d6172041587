// LightSampler: picks a point on the scene's emitters, each emitting triangle with
// probability proportional to its area times its radiance's luminance (for a single emitter:
// uniform by area, as Mitsuba samples one area light).
#pragma once

#include <cstdint>
#include <vector>

#include "scene.h"

namespace aliquot {

struct LightSample {
    Vec3 position;
    Vec3 normal;      // unit, the emitting side
    Vec3 radiance;
    float pdf_area;   // with respect to area on the emitter
};

class LightSampler {
public:
    explicit LightSampler(const Scene& scene);

    bool empty() const { return triangles_.empty(); }
    LightSample sample(float u_select, float u1, float u2) const;
    // Area density of sampling the given point of the given mesh triangle (0 if not emitting).
    float pdf_area(uint32_t mesh, uint32_t triangle) const;

private:
    struct EmitterTriangle {
        Vec3 p0, e1, e2, normal, radiance;
        uint32_t mesh, triangle;
        float pdf_area = 0;  // filled once the total weight is known
    };
    std::vector<EmitterTriangle> triangles_;
    std::vector<float> cdf_;  // inclusive, normalised to 1
    // pdf_area per mesh triangle: weight / (area * total_weight) = luminance / total_weight.
    std::vector<std::vector<float>> pdf_by_mesh_;
};

}  // namespace aliquot
