#include "path_tracer.h"

#include <cmath>
#include <limits>
#include <numbers>

#include "warp.h"

namespace aliquot {

namespace {

constexpr float kInvPi = float(1.0 / std::numbers::pi);

// Rays leave a surface from a point pushed off it along the geometric normal, to the side
// they travel to; scaled by the point's magnitude so float spacing never swallows it.
float offset_scale(const Vec3& p) {
    return 1e-4f *
           (1.0f + std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z))));
}
Vec3 offset_origin(const Vec3& p, const Vec3& ng, float scale, const Vec3& dir) {
    return dot(dir, ng) > 0 ? p + ng * scale : p - ng * scale;
}

float power_heuristic(float a, float b) {
    const float a2 = a * a;
    return a2 > 0 ? a2 / (a2 + b * b) : 0.0f;
}

// Unpolarised Fresnel reflectance of a smooth dielectric interface; eta = n_t / n_i.
float fresnel_dielectric(float cos_i, float eta, float& cos_t) {
    const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) {
        cos_t = 0;
        return 1.0f;  // total internal reflection
    }
    cos_t = std::sqrt(1.0f - sin2_t);
    const float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    const float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

}  // namespace

PathTracer::PathTracer(const Scene& scene)
    : scene_(scene), embree_(scene), lights_(scene) {}

const Material& PathTracer::material_at(const Hit& hit) const {
    const uint32_t index = hit.geom_id == embree_.sphere_geometry()
                               ? scene_.spheres[hit.prim_id].material
                               : scene_.meshes[hit.geom_id].material;
    return scene_.materials[index];
}

Radiance PathTracer::radiance(const Vec3& origin, const Vec3& direction,
                              SampleRng& rng) const {
    Hit hit;
    const bool found =
        embree_.intersect(origin, direction, std::numeric_limits<float>::infinity(), hit);
    return radiance(origin, direction, found ? &hit : nullptr, rng);
}

// One bounce loop, kept whole on purpose (longer than our ~80-line rule): the path's
// state (throughput, IOR product, the previous BSDF pdf for MIS, the order of random
// draws) lives in its locals, and the order in which it draws from `rng` is the sample's
// identity; split into functions, that state and order would be threaded through every
// call.
Radiance PathTracer::radiance(const Vec3& origin, const Vec3& direction, const Hit* first,
                              SampleRng& rng) const {
    Radiance out;
    Vec3 L{0, 0, 0};
    Vec3 beta{1, 1, 1};
    float eta = 1.0f;            // product of relative IORs crossed: Mitsuba's RR uses it
    float prev_bsdf_pdf = 0.0f;  // solid-angle pdf of the direction that led here
    bool prev_specular = true;   // camera rays and delta lobes take emission unweighted
    Vec3 o = origin, d = direction;
    const int max_depth = scene_.max_depth;

    out.rays = 1;  // the first ray, traced by the caller
    if (!first) return out;
    Hit hit = *first;
    for (int depth = 0;; ++depth) {
        const Vec3 p = o + d * hit.t;
        const float cos_ng = dot(d, hit.ng);
        const bool front = cos_ng < 0;

        // Emission found by the path itself, weighted against light sampling unless the
        // previous bounce could not have been light-sampled.
        if (front && hit.geom_id != embree_.sphere_geometry()) {
            const TriangleMesh& mesh = scene_.meshes[hit.geom_id];
            if (mesh.is_emitter()) {
                float w = 1.0f;
                if (!prev_specular) {
                    const float light_pdf =
                        lights_.pdf_area(hit.geom_id) * hit.t * hit.t / -cos_ng;
                    w = power_heuristic(prev_bsdf_pdf, light_pdf);
                }
                L += beta * mesh.emission * w;
            }
        }
        // Path length counted in segments, as Mitsuba's max_depth: the next vertex would
        // make depth + 2 segments.
        if (depth + 1 >= max_depth) break;
        const float offset = offset_scale(p);

        const Material& mat = material_at(hit);
        const Vec3 n = front ? hit.ng : -hit.ng;  // facing the incoming ray
        Vec3 wo;
        switch (mat.kind) {
            case Material::Kind::Diffuse: {
                if (!lights_.empty()) {
                    const float us = rng.next_float(), u1 = rng.next_float(),
                                u2 = rng.next_float();
                    const LightSample ls = lights_.sample(us, u1, u2);
                    Vec3 to_light = ls.position - p;
                    const float dist2 = dot(to_light, to_light);
                    const float dist = std::sqrt(dist2);
                    to_light = to_light / dist;
                    const float cos_light = -dot(to_light, ls.normal);
                    const float cos_surf = dot(to_light, n);
                    if (cos_light > 0 && cos_surf > 0 && ls.pdf_area > 0) {
                        const Vec3 so = offset_origin(p, hit.ng, offset, to_light);
                        ++out.rays;
                        // Stop short of the light so its own surface does not occlude.
                        if (!embree_.occluded(so, to_light, dist * (1.0f - 1e-3f))) {
                            const float light_pdf = ls.pdf_area * dist2 / cos_light;
                            const float bsdf_pdf = cos_surf * kInvPi;
                            const float w = power_heuristic(light_pdf, bsdf_pdf);
                            L += beta * mat.reflectance * ls.radiance *
                                 (kInvPi * cos_surf * w / light_pdf);
                        }
                    }
                }
                const float u1 = rng.next_float(), u2 = rng.next_float();
                wo = cosine_hemisphere(n, u1, u2);
                prev_bsdf_pdf = std::max(dot(wo, n), 0.0f) * kInvPi;
                beta *= mat.reflectance;  // f * cos / pdf for a Lambertian lobe
                prev_specular = false;
                break;
            }
            case Material::Kind::Mirror: {
                wo = d - n * (2.0f * dot(d, n));
                beta *= mat.reflectance;
                prev_specular = true;
                break;
            }
            case Material::Kind::Dielectric: {
                const float cos_i = -dot(d, n);
                const float eta_rel = front ? mat.ior : 1.0f / mat.ior;
                float cos_t;
                const float F = fresnel_dielectric(cos_i, eta_rel, cos_t);
                if (rng.next_float() < F) {
                    wo = d + n * (2.0f * cos_i);
                } else {
                    wo = normalize(d / eta_rel + n * (cos_i / eta_rel - cos_t));
                    // Radiance is compressed into the denser medium (Veach's
                    // thesis, 5.2).
                    beta *= 1.0f / (eta_rel * eta_rel);
                    eta *= eta_rel;
                }
                prev_specular = true;
                break;
            }
        }

        // Russian roulette after the fifth vertex, with Mitsuba's survival probability.
        if (depth + 1 >= kRussianRouletteDepth) {
            const float q = std::min(max_component(beta) * eta * eta, 0.95f);
            if (!(rng.next_float() < q)) break;
            beta *= 1.0f / q;
        }
        if (max_component(beta) <= 0.0f) break;
        o = offset_origin(p, hit.ng, offset, wo);
        d = wo;
        ++out.rays;
        if (!embree_.intersect(o, d, std::numeric_limits<float>::infinity(), hit)) break;
    }
    out.value = L;
    return out;
}

}  // namespace aliquot
