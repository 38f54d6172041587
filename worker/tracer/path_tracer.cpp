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

Radiance PathTracer::radiance(const Vec3& origin, const Vec3& direction,
                              SampleRng& rng) const {
    Radiance out;
    radiance_batch(origin, &direction, 1, &rng, &out);
    return out;
}

const Material* PathTracer::arrive(PathState& s, const Hit& hit) const {
    s.shadow = false;
    const float cos_ng = dot(s.d, hit.ng);
    // Emission found by the path itself, weighted against light sampling unless the
    // previous bounce could not have been light-sampled.
    if (cos_ng < 0 && hit.geom_id != embree_.sphere_geometry()) {
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
    if (s.depth + 1 >= scene_.max_depth) return nullptr;
    return &material_at(hit);
}

// The draws are the sample's identity: light pick and point, bounce, then roulette from
// the fifth vertex on, as one path's shading always drew them.
void PathTracer::add_diffuse(DiffuseLanes& l, int path, const PathState& s,
                             const Hit& hit, const Material& mat, SampleRng& rng) const {
    const int j = l.count++;
    l.path[j] = path;
    l.p.set(j, s.o + s.d * hit.t);
    l.ng.set(j, hit.ng);
    l.n.set(j, dot(s.d, hit.ng) < 0 ? hit.ng : -hit.ng);  // facing the incoming ray
    l.beta.set(j, s.beta);
    l.reflectance.set(j, mat.reflectance);
    l.eta[j] = s.eta;
    if (lights_.empty()) {
        l.light_pdf[j] = 0.0f;  // no shadow ray; the other light inputs go unused
        l.light_u1[j] = l.light_u2[j] = 0.0f;
        for (DiffuseLanes::Vec3Lanes* v :
             {&l.light_p0, &l.light_e1, &l.light_e2, &l.light_normal, &l.light_radiance})
            v->set(j, Vec3(0.0f));
    } else {
        const Emitter& e = lights_.pick(rng.next_float());
        l.light_u1[j] = rng.next_float();
        l.light_u2[j] = rng.next_float();
        l.light_p0.set(j, e.p0);
        l.light_e1.set(j, e.e1);
        l.light_e2.set(j, e.e2);
        l.light_normal.set(j, e.normal);
        l.light_radiance.set(j, e.radiance);
        l.light_pdf[j] = e.pdf_area;
    }
    l.u1[j] = rng.next_float();
    l.u2[j] = rng.next_float();
    l.roulette[j] = s.depth + 1 >= kRussianRouletteDepth;
    l.u_roulette[j] = l.roulette[j] ? rng.next_float() : 0.0f;
}

bool PathTracer::scatter_specular(PathState& s, const Hit& hit, const Material& mat,
                                  SampleRng& rng) const {
    const Vec3 p = s.o + s.d * hit.t;
    const bool front = dot(s.d, hit.ng) < 0;
    const Vec3 n = front ? hit.ng : -hit.ng;  // facing the incoming ray
    Vec3 wo;
    if (mat.kind == Material::Kind::Mirror) {
        wo = s.d - n * (2.0f * dot(s.d, n));
        s.beta *= mat.reflectance;
    } else {
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
    }
    s.prev_specular = true;

    // Russian roulette after the fifth vertex.
    if (s.depth + 1 >= kRussianRouletteDepth) {
        const float q = survival(s.beta, s.eta);
        if (!(rng.next_float() < q)) return false;
        s.beta *= 1.0f / q;
    }
    if (max_component(s.beta) <= 0.0f) return false;
    s.o = offset_origin(p, hit.ng, offset_scale(p), wo);
    s.d = wo;
    ++s.rays;
    ++s.depth;
    return true;
}

namespace {

// Takes lane j's shading back into its path; whether the path goes on.
bool finish_diffuse(const DiffuseLanes& l, int j, PathState& s) {
    if (l.shadow[j]) {
        s.shadow = true;
        s.shadow_origin = l.shadow_origin.get(j);
        s.shadow_dir = l.shadow_dir.get(j);
        s.shadow_tmax = l.shadow_tmax[j];
        s.shadow_L = l.shadow_L.get(j);
        ++s.rays;
    }
    s.prev_bsdf_pdf = l.bsdf_pdf[j];
    s.prev_specular = false;
    s.beta = l.beta.get(j);
    if (!l.alive[j]) return false;
    s.o = l.origin.get(j);
    s.d = l.dir.get(j);
    ++s.rays;
    ++s.depth;
    return true;
}

}  // namespace

void PathTracer::radiance_batch(const Vec3& origin, const Vec3* dirs, int count,
                                SampleRng* rngs, Radiance* out) const {
    static_assert(kBatch <= DiffuseLanes::kMax);
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
    DiffuseLanes lanes;
    std::array<bool, kBatch> going;
    std::array<Vec3, kPacket> origins, directions;
    std::array<float, kPacket> tmax;
    std::array<bool, kPacket> blocked, hit_found;
    std::array<Hit, kPacket> packet_hits;
    while (n_active > 0) {
        // Shade every vertex: specular ones one by one, diffuse ones together.
        lanes.count = 0;
        for (int a = 0; a < n_active; ++a) {
            const int i = active[a];
            const Material* mat = arrive(paths[i], hits[i]);
            going[i] = false;
            if (!mat) continue;
            if (mat->kind == Material::Kind::Diffuse)
                add_diffuse(lanes, i, paths[i], hits[i], *mat, rngs[i]);
            else
                going[i] = scatter_specular(paths[i], hits[i], *mat, rngs[i]);
        }
        shade_diffuse(lanes);
        for (int j = 0; j < lanes.count; ++j)
            going[lanes.path[j]] = finish_diffuse(lanes, j, paths[lanes.path[j]]);

        int n_next = 0, n_shadow = 0;
        std::array<int, kBatch> shadowed;
        for (int a = 0; a < n_active; ++a) {
            const int i = active[a];
            if (going[i]) next[n_next++] = i;
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
