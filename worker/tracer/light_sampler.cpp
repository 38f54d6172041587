#include "light_sampler.h"

#include <algorithm>
#include <cmath>

namespace aliquot {

LightSampler::LightSampler(const Scene& scene) : pdf_by_mesh_(scene.meshes.size(), 0.0f) {
    double total = 0;
    std::vector<double> weights;
    std::vector<uint32_t> mesh_of;  // by triangle
    for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
        const TriangleMesh& mesh = scene.meshes[m];
        if (!mesh.is_emitter()) continue;
        for (uint32_t t = 0; t < mesh.triangles.size(); ++t) {
            const auto& tri = mesh.triangles[t];
            const Vec3 p0 = mesh.positions[tri[0]];
            const Vec3 e1 = mesh.positions[tri[1]] - p0;
            const Vec3 e2 = mesh.positions[tri[2]] - p0;
            const Vec3 c = cross(e1, e2);
            const float area = 0.5f * length(c);
            if (!(area > 0)) continue;
            triangles_.push_back({p0, e1, e2, c / (2 * area), mesh.emission, 0.0f});
            mesh_of.push_back(m);
            const double w = double(area) * luminance(mesh.emission);
            weights.push_back(w);
            total += w;
        }
    }
    double running = 0;
    for (double w : weights) {
        running += w;
        cdf_.push_back(float(running / total));
    }
    if (!cdf_.empty()) cdf_.back() = 1.0f;
    // A triangle picked by area x luminance and a point uniform on it: the density per
    // unit area is luminance / total, the same on every triangle of a mesh.
    for (uint32_t m = 0; m < scene.meshes.size(); ++m)
        if (scene.meshes[m].is_emitter() && total > 0)
            pdf_by_mesh_[m] = float(luminance(scene.meshes[m].emission) / total);
    for (size_t t = 0; t < triangles_.size(); ++t)
        triangles_[t].pdf_area = pdf_by_mesh_[mesh_of[t]];
}

const Emitter& LightSampler::pick_by_search(float u_select) const {
    const size_t i = std::min<size_t>(
        std::upper_bound(cdf_.begin(), cdf_.end(), u_select) - cdf_.begin(),
        cdf_.size() - 1);
    return triangles_[i];
}

LightSample LightSampler::sample(float u_select, float u1, float u2) const {
    const Emitter& tri = pick(u_select);
    // Uniform point on the triangle (square-root parameterisation).
    const float su = std::sqrt(u1);
    const float b1 = 1.0f - su, b2 = u2 * su;
    return {tri.p0 + tri.e1 * b1 + tri.e2 * b2, tri.normal, tri.radiance, tri.pdf_area};
}

float LightSampler::pdf_area(uint32_t mesh) const { return pdf_by_mesh_[mesh]; }

}  // namespace aliquot
