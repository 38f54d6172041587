#include "path_tracer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

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

// One vertex of a path, kept whole on purpose (longer than our ~80-line rule): the order
// in which it draws from `rng` is the sample's identity, and split into functions that
// order would be threaded through every call. What radiance() kept in locals between
// vertices is the PathState, so that a batch of paths can advance a vertex at a time.
bool PathTracer::shade(PathState& s, const Hit& hit, SampleRng& rng) const {
    s.shadow = false;
    const Vec3 p = s.o + s.d * hit.t;
    const float cos_ng = dot(s.d, hit.ng);
    const bool front = cos_ng < 0;

    // Emission found by the path itself, weighted against light sampling unless the
    // previous bounce could not have been light-sampled.
    if (front && hit.geom_id != embree_.sphere_geometry()) {
        const TriangleMesh& mesh = scene_.meshes[hit.geom_id];
        if (mesh.is_emitter()) {
            float w = 1.0f;
            if (!s.prev_specular) {
                const float light_pdf =
                    lights_.pdf_area(hit.geom_id) * hit.t * hit.t / -cos_ng;
                w = power_heuristic(s.prev_bsdf_pdf, light_pdf);
            }
            s.L += s.beta * mesh.emission * w;
        }
    }
    // Path length counted in segments, as Mitsuba's max_depth: the next vertex would
    // make depth + 2 segments.
    if (s.depth + 1 >= scene_.max_depth) return false;
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
                    // The shadow ray is the caller's to trace (alone or in a packet);
                    // what it adds if nothing is in the way is fixed now.
                    s.shadow = true;
                    s.shadow_origin = offset_origin(p, hit.ng, offset, to_light);
                    s.shadow_dir = to_light;
                    // Stop short of the light so its own surface does not occlude.
                    s.shadow_tmax = dist * (1.0f - 1e-3f);
                    ++s.rays;
                    const float light_pdf = ls.pdf_area * dist2 / cos_light;
                    const float bsdf_pdf = cos_surf * kInvPi;
                    const float w = power_heuristic(light_pdf, bsdf_pdf);
                    s.shadow_L = s.beta * mat.reflectance * ls.radiance *
                                 (kInvPi * cos_surf * w / light_pdf);
                }
            }
            const float u1 = rng.next_float(), u2 = rng.next_float();
            wo = cosine_hemisphere(n, u1, u2);
            s.prev_bsdf_pdf = std::max(dot(wo, n), 0.0f) * kInvPi;
            s.beta *= mat.reflectance;  // f * cos / pdf for a Lambertian lobe
            s.prev_specular = false;
            break;
        }
        case Material::Kind::Mirror: {
            wo = s.d - n * (2.0f * dot(s.d, n));
            s.beta *= mat.reflectance;
            s.prev_specular = true;
            break;
        }
        case Material::Kind::Dielectric: {
            const float cos_i = -dot(s.d, n);
            const float eta_rel = front ? mat.ior : 1.0f / mat.ior;
            float cos_t;
            const float F = fresnel_dielectric(cos_i, eta_rel, cos_t);
            if (rng.next_float() < F) {
                wo = s.d + n * (2.0f * cos_i);
            } else {
                wo = normalize(s.d / eta_rel + n * (cos_i / eta_rel - cos_t));
                // Radiance is compressed into the denser medium (Veach's thesis, 5.2).
                s.beta *= 1.0f / (eta_rel * eta_rel);
                s.eta *= eta_rel;
            }
            s.prev_specular = true;
            break;
        }
    }

    // Russian roulette after the fifth vertex, with Mitsuba's survival probability.
    if (s.depth + 1 >= kRussianRouletteDepth) {
        const float q = std::min(max_component(s.beta) * s.eta * s.eta, 0.95f);
        if (!(rng.next_float() < q)) return false;
        s.beta *= 1.0f / q;
    }
    if (max_component(s.beta) <= 0.0f) return false;
    s.o = offset_origin(p, hit.ng, offset, wo);
    s.d = wo;
    ++s.rays;
    ++s.depth;
    return true;
}

Radiance PathTracer::radiance(const Vec3& origin, const Vec3& direction, const Hit* first,
                              SampleRng& rng) const {
    PathState s;
    s.o = origin;
    s.d = direction;
    if (!first) return {s.L, s.rays};
    Hit hit = *first;
    while (true) {
        const bool more = shade(s, hit, rng);
        if (s.shadow && !embree_.occluded(s.shadow_origin, s.shadow_dir, s.shadow_tmax))
            s.L += s.shadow_L;
        if (!more) break;
        if (!embree_.intersect(s.o, s.d, std::numeric_limits<float>::infinity(), hit))
            break;
    }
    return {s.L, s.rays};
}

void PathTracer::radiance_batch(const Vec3& origin, const Vec3* dirs, int count,
                                SampleRng* rngs, Radiance* out) const {
    if (count < 0 || count > kBatch)
        throw std::invalid_argument("radiance_batch: more paths than a batch holds");
    constexpr int kPacket = EmbreeScene::kPacket;
    std::array<PathState, kBatch> paths;
    std::array<Hit, kBatch> hits;
    std::array<bool, kBatch> found;
    for (int b = 0; b < count; b += kPacket)  // camera rays: kPacket per packet from b
        embree_.intersect_packet(origin, dirs + b, std::min(kPacket, count - b),
                                 hits.data() + b, found.data() + b);
    // Paths still going, in sample order; each pass advances every one a vertex.
    std::array<int, kBatch> active, next;
    int n_active = 0;
    for (int i = 0; i < count; ++i) {
        paths[i].o = origin;
        paths[i].d = dirs[i];
        if (found[i]) active[n_active++] = i;
    }
    std::array<Vec3, kPacket> origins, directions;
    std::array<float, kPacket> tmax;
    std::array<bool, kPacket> blocked, hit_found;
    std::array<Hit, kPacket> packet_hits;
    while (n_active > 0) {
        int n_next = 0, n_shadow = 0;
        std::array<int, kBatch> shadowed;
        for (int a = 0; a < n_active; ++a) {
            const int i = active[a];
            if (shade(paths[i], hits[i], rngs[i])) next[n_next++] = i;
            if (paths[i].shadow) shadowed[n_shadow++] = i;
        }
        // Shadow rays, then the next bounces, kPacket at a time in sample order.
        for (int b = 0; b < n_shadow; b += kPacket) {
            const int m = std::min(kPacket, n_shadow - b);
            for (int j = 0; j < m; ++j) {
                const PathState& s = paths[shadowed[b + j]];
                origins[j] = s.shadow_origin;
                directions[j] = s.shadow_dir;
                tmax[j] = s.shadow_tmax;
            }
            embree_.occluded_packet(origins.data(), directions.data(), tmax.data(), m,
                                    blocked.data());
            for (int j = 0; j < m; ++j)
                if (!blocked[j])
                    paths[shadowed[b + j]].L += paths[shadowed[b + j]].shadow_L;
        }
        n_active = 0;
        for (int b = 0; b < n_next; b += kPacket) {
            const int m = std::min(kPacket, n_next - b);
            for (int j = 0; j < m; ++j) {
                origins[j] = paths[next[b + j]].o;
                directions[j] = paths[next[b + j]].d;
            }
            embree_.intersect_packet(origins.data(), directions.data(), m,
                                     packet_hits.data(), hit_found.data());
            for (int j = 0; j < m; ++j)
                if (hit_found[j]) {
                    hits[next[b + j]] = packet_hits[j];
                    active[n_active++] = next[b + j];
                }
        }
    }
    for (int i = 0; i < count; ++i) out[i] = {paths[i].L, paths[i].rays};
}

}  // namespace aliquot
