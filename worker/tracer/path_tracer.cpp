#include "path_tracer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "shading.h"
#include "warp.h"

namespace aliquot {

namespace {

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

FirstHit PathTracer::first_hit(const Vec3& dir, const Hit& hit) const {
    // OIDN's documented first-hit features: a diffuse surface's reflectance, a mirror's
    // (its reflectivity), 1 for a dielectric; the shading normal, here the geometric one
    // (no normal interpolation), turned to face the ray as the shading does.
    //
    // An emitter seen from its emitting side records its emission's colour, normalised to
    // its largest component (1 for a white light), not its surface's reflectance: OIDN's
    // manual ("Albedos") asks only for the surfaces' "approximate color ... independent
    // of illumination" between 0 and 1 and says nothing of emitters; with the reflectance
    // a light has its ceiling's albedo and normal and OIDN, given no edge, blurred the
    // light into the ceiling (docs/DENOISE.md, "the light's edge"). A light's colour is
    // what stays of it when its brightness, the illumination, is divided out. Only the
    // camera ray's hit is read here, with first hits asked for: the paths' loop is
    // untouched.
    const Material& mat = material_at(hit);
    FirstHit out;
    const bool front = dot(dir, hit.ng) < 0;
    out.albedo = mat.kind == Material::Kind::Dielectric ? Vec3(1.0f) : mat.reflectance;
    if (front && hit.geom_id != embree_.sphere_geometry()) {
        const TriangleMesh& mesh = scene_.meshes[hit.geom_id];
        if (mesh.is_emitter()) out.albedo = mesh.emission / max_component(mesh.emission);
    }
    out.normal = front ? hit.ng : -hit.ng;
    return out;
}

Radiance PathTracer::radiance(const Vec3& origin, const Vec3& direction,
                              SampleRng& rng) const {
    Radiance out;
    radiance_batch(origin, &direction, 1, &rng, &out);
    return out;
}

// Inlined into radiance_batch's loop over the active paths, once a vertex: a call there
// cost 1.4 % of a sample's instructions (callgrind, cornell-box at 4 spp).
[[gnu::always_inline]] inline const Material* PathTracer::arrive(PathLanes& l, int i,
                                                                 const Hit& hit) const {
    l.shadow[i] = 0;
    l.diffuse[i] = 0;
    const float cos_ng = dot(l.d.get(i), hit.ng);
    // Emission found by the path itself, weighted against light sampling unless the
    // previous bounce could not have been light-sampled.
    if (cos_ng < 0 && hit.geom_id != embree_.sphere_geometry()) {
        const TriangleMesh& mesh = scene_.meshes[hit.geom_id];
        if (mesh.is_emitter()) {
            float w = 1.0f;
            if (!l.prev_specular[i]) {
                const float light_pdf =
                    lights_.pdf_area(hit.geom_id) * hit.t * hit.t / -cos_ng;
                w = power_heuristic(l.prev_bsdf_pdf[i], light_pdf);
            }
            l.L.set(i, l.L.get(i) + l.beta.get(i) * mesh.emission * w);
        }
    }
    // Path length counted in segments, as Mitsuba's max_depth: the next vertex would
    // make depth + 2 segments.
    if (l.depth[i] + 1 >= scene_.max_depth) return nullptr;
    return &material_at(hit);
}

void PathTracer::prepare_diffuse(PathLanes& l, int i, const Material& mat) const {
    l.diffuse[i] = 1;
    l.prev_specular[i] = 0;
    l.reflectance.set(i, mat.reflectance);
    l.roulette[i] = l.depth[i] + 1 >= kRussianRouletteDepth;
}

void PathTracer::pick_lights(PathLanes& l, int count, const int* active,
                             int n_active) const {
    if (lights_.empty()) return;  // light_pdf stays 0: no shadow rays
    const std::vector<Emitter>& emitters = lights_.emitters();
    if (emitters.size() <= LightSampler::kFew) {
        pick_few_lights(l, count, emitters.data(), lights_.cdf().data(),
                        int(emitters.size()));
        return;
    }
    for (int a = 0; a < n_active; ++a) {
        const int i = active[a];
        if (!l.diffuse[i]) continue;
        const Emitter& e = lights_.pick(l.u_select[i]);
        l.light_p0.set(i, e.p0);
        l.light_e1.set(i, e.e1);
        l.light_e2.set(i, e.e2);
        l.light_normal.set(i, e.normal);
        l.light_radiance.set(i, e.radiance);
        l.light_pdf[i] = e.pdf_area;
    }
}

bool PathTracer::scatter_specular(PathLanes& l, int i, const Hit& hit,
                                  const Material& mat) const {
    const Vec3 d = l.d.get(i);
    Vec3 beta = l.beta.get(i);
    const Vec3 p = l.o.get(i) + d * hit.t;
    const bool front = dot(d, hit.ng) < 0;
    const Vec3 n = front ? hit.ng : -hit.ng;  // facing the incoming ray
    Vec3 wo;
    if (mat.kind == Material::Kind::Mirror) {
        wo = d - n * (2.0f * dot(d, n));
        beta *= mat.reflectance;
    } else {
        const float cos_i = -dot(d, n);
        const float eta_rel = front ? mat.ior : 1.0f / mat.ior;
        float cos_t;
        const float F = fresnel_dielectric(cos_i, eta_rel, cos_t);
        if (l.next_float(i) < F) {
            wo = d + n * (2.0f * cos_i);
        } else {
            wo = normalize(d / eta_rel + n * (cos_i / eta_rel - cos_t));
            // Radiance is compressed into the denser medium (Veach's thesis, 5.2).
            beta *= 1.0f / (eta_rel * eta_rel);
            l.eta[i] *= eta_rel;
        }
    }
    l.prev_specular[i] = 1;

    // Russian roulette after the fifth vertex.
    bool going = true;
    if (l.depth[i] + 1 >= kRussianRouletteDepth) {
        const float q = survival(beta, l.eta[i]);
        going = l.next_float(i) < q;
        beta *= 1.0f / q;
    }
    l.beta.set(i, beta);
    if (!going || max_component(beta) <= 0.0f) return false;
    l.o.set(i, offset_origin(p, hit.ng, offset_scale(p), wo));
    l.d.set(i, wo);
    return true;
}

void PathTracer::radiance_batch(const Vec3& origin, const Vec3* dirs, int count,
                                SampleRng* rngs, Radiance* out,
                                FirstHit* first_hits) const {
    static_assert(kBatch <= PathLanes::kMax);
    if (count < 0) throw std::invalid_argument("radiance_batch: a negative count");
    constexpr int kPacket = EmbreeScene::kPacket;
    const int lanes = std::min(count, kBatch);
    PathLanes l;
    std::array<Hit, kBatch> hits;
    std::array<int, kBatch> path_of;  // the path (index into dirs) in each lane
    // Paths still going, oldest first; each pass advances every one a vertex.
    std::array<int, kBatch> active, next, shadowed, ended;
    // Lanes whose path ended, in the order the paths ended: the next paths take them.
    std::array<int, kBatch> free_lanes;
    int n_active = 0, n_free = 0, started = 0;
    for (int i = 0; i < lanes; ++i) {
        // shade_diffuse reads every lane below `lanes` and keeps the others' state: give
        // its inputs values before any lane is diffuse.
        l.diffuse[i] = l.roulette[i] = 0;
        for (PathLanes::Vec3Lanes* v : {&l.reflectance, &l.light_p0, &l.light_e1,
                                        &l.light_e2, &l.light_normal, &l.light_radiance})
            v->set(i, Vec3(0.0f));
        l.light_pdf[i] = 0.0f;
        free_lanes[n_free++] = i;
    }
    const auto finish = [&](int i) {
        const int p = path_of[i];
        out[p] = {l.L.get(i), l.rays[i]};
        rngs[p].set_state(l.rng_state[i]);
        free_lanes[n_free++] = i;
    };
    // The lanes freed take the next paths, in order, their camera rays kPacket at a time
    // from the one origin; a camera ray that hits nothing ends its path at once, and its
    // lane takes another. So the lanes stay full while paths are left, and which paths
    // share a pass (and so Embree's packets) follows from the paths' order alone.
    std::array<Hit, kPacket> camera_hits;
    std::array<bool, kPacket> camera_found;
    std::array<int, kPacket> taking;
    const auto refill = [&] {
        while (n_free > 0 && started < count) {
            const int m = std::min({n_free, count - started, kPacket});
            for (int j = 0; j < m; ++j) taking[j] = free_lanes[j];
            n_free -= m;
            std::copy(free_lanes.begin() + m, free_lanes.begin() + m + n_free,
                      free_lanes.begin());
            embree_.intersect_packet(origin, dirs + started, m, camera_hits.data(),
                                     camera_found.data());
            if (first_hits)
                for (int j = 0; j < m; ++j)
                    first_hits[started + j] =
                        camera_found[j] ? first_hit(dirs[started + j], camera_hits[j])
                                        : FirstHit{};
            for (int j = 0; j < m; ++j) {
                const int i = taking[j], p = started + j;
                path_of[i] = p;
                l.o.set(i, origin);
                l.d.set(i, dirs[p]);
                l.L.set(i, Vec3(0.0f));
                l.beta.set(i, Vec3(1.0f));
                l.eta[i] = 1.0f;
                l.prev_bsdf_pdf[i] = 0.0f;
                l.prev_specular[i] = 1;
                l.depth[i] = 0;
                l.rays[i] = 1;
                l.rng_state[i] = rngs[p].state();
                l.rng_inc[i] = rngs[p].increment();
                // A lane the shading loops read but skip still holds defined values.
                l.t[i] = camera_found[j] ? camera_hits[j].t : 0.0f;
                l.ng.set(i, camera_found[j] ? camera_hits[j].ng : Vec3(0.0f));
                if (camera_found[j]) {
                    hits[i] = camera_hits[j];
                    active[n_active++] = i;
                } else {
                    finish(i);
                }
            }
            started += m;
        }
    };
    std::array<bool, kBatch> going;
    RayLanes rays;
    std::array<bool, kPacket> blocked, hit_found;
    std::array<Hit, kPacket> packet_hits;
    refill();
    while (n_active > 0) {
        // Shade every vertex: specular ones one by one, diffuse ones together.
        for (int a = 0; a < n_active; ++a) {
            const int i = active[a];
            const Material* mat = arrive(l, i, hits[i]);
            going[i] = false;
            if (!mat) continue;
            if (mat->kind == Material::Kind::Diffuse)
                prepare_diffuse(l, i, *mat);
            else
                going[i] = scatter_specular(l, i, hits[i], *mat);
        }
        draw_diffuse_uniforms(l, lanes, !lights_.empty());
        pick_lights(l, lanes, active.data(), n_active);
        shade_diffuse(l, lanes);

        // The lists of paths with a shadow ray, going on and ending, in the active order,
        // made without branches: which paths end or cast a shadow ray is random, and a
        // mispredicted branch a path cost more than the rest of this loop.
        int n_next = 0, n_shadow = 0, n_ended = 0;
        for (int a = 0; a < n_active; ++a) {
            const int i = active[a];
            const bool goes = l.diffuse[i] ? l.alive[i] != 0 : going[i];
            const bool shadow = l.shadow[i] != 0;
            shadowed[n_shadow] = i;
            n_shadow += shadow;
            next[n_next] = i;
            n_next += goes;
            ended[n_ended] = i;
            n_ended += !goes;
            l.rays[i] += uint32_t(shadow) + uint32_t(goes);
            l.depth[i] += goes;
            l.diffuse[i] = 0;  // shade_diffuse leaves paths that ended alone
        }
        // Shadow rays, then the next bounces, kPacket at a time in the active order.
        for (int b = 0; b < n_shadow; b += kPacket) {
            const int m = std::min(kPacket, n_shadow - b);
            for (int j = 0; j < m; ++j) {
                const int i = shadowed[b + j];
                rays.set(j, l.shadow_origin.get(i), l.shadow_dir.get(i),
                         l.shadow_tmax[i]);
            }
            embree_.occluded_lanes(rays, m, blocked.data());
            for (int j = 0; j < m; ++j) {
                const int i = shadowed[b + j];
                if (!blocked[j]) l.L.set(i, l.L.get(i) + l.shadow_L.get(i));
            }
        }
        for (int e = 0; e < n_ended; ++e) finish(ended[e]);
        const int n_shaded_ended = n_ended;
        n_active = 0;
        for (int b = 0; b < n_next; b += kPacket) {
            const int m = std::min(kPacket, n_next - b);
            for (int j = 0; j < m; ++j) {
                const int i = next[b + j];
                rays.set(j, l.o.get(i), l.d.get(i),
                         std::numeric_limits<float>::infinity());
            }
            embree_.intersect_lanes(rays, m, packet_hits.data(), hit_found.data());
            for (int j = 0; j < m; ++j) {
                // A path that hit nothing ends (below).
                const int i = next[b + j];
                hits[i] = packet_hits[j];
                l.t[i] = packet_hits[j].t;
                l.ng.set(i, packet_hits[j].ng);
                active[n_active] = i;
                n_active += hit_found[j];
                ended[n_ended] = i;
                n_ended += !hit_found[j];
            }
        }
        for (int e = n_shaded_ended; e < n_ended; ++e) finish(ended[e]);
        refill();
    }
}

}  // namespace aliquot
