#include "diffuse_lanes.h"

#include "shading.h"
#include "warp.h"

namespace aliquot {

// The loop body is one-path shading written without branches: what a path would skip
// (the shadow ray when the light faces away, roulette before the fifth vertex) is
// computed anyway and selected away, so the compiler can run lanes side by side.
// Computing it changes no result: each lane's operations are its own path's.
__attribute__((target_clones("avx512f", "avx2", "default"))) void shade_diffuse(
    DiffuseLanes& l) {
    for (int j = 0; j < l.count; ++j) {
        const Vec3 p = l.p.get(j), ng = l.ng.get(j), n = l.n.get(j);
        const Vec3 reflectance = l.reflectance.get(j);
        Vec3 beta = l.beta.get(j);
        const float offset = offset_scale(p);

        // Next-event estimation: a uniform point on the picked triangle (square-root
        // parameterisation), weighted against the bounce by the power heuristic.
        const float su = std::sqrt(l.light_u1[j]);
        const float b1 = 1.0f - su, b2 = l.light_u2[j] * su;
        const Vec3 on_light =
            l.light_p0.get(j) + l.light_e1.get(j) * b1 + l.light_e2.get(j) * b2;
        Vec3 to_light = on_light - p;
        const float dist2 = dot(to_light, to_light);
        const float dist = std::sqrt(dist2);
        to_light = to_light / dist;
        const float cos_light = -dot(to_light, l.light_normal.get(j));
        const float cos_surf = dot(to_light, n);
        const float pdf_area = l.light_pdf[j];
        l.shadow[j] = (cos_light > 0) & (cos_surf > 0) & (pdf_area > 0);
        l.shadow_origin.set(j, offset_origin(p, ng, offset, to_light));
        l.shadow_dir.set(j, to_light);
        // Stop short of the light so its own surface does not occlude.
        l.shadow_tmax[j] = dist * (1.0f - 1e-3f);
        const float light_pdf = pdf_area * dist2 / cos_light;
        const float w = power_heuristic(light_pdf, cos_surf * kInvPi);
        l.shadow_L.set(j, beta * reflectance * l.light_radiance.get(j) *
                              (kInvPi * cos_surf * w / light_pdf));

        // The bounce: f * cos / pdf of a Lambertian lobe is its reflectance.
        const Vec3 wo = cosine_hemisphere(n, l.u1[j], l.u2[j]);
        l.bsdf_pdf[j] = std::max(dot(wo, n), 0.0f) * kInvPi;
        beta *= reflectance;

        const bool roulette = l.roulette[j] != 0;
        const float q = survival(beta, l.eta[j]);
        const bool survived = !roulette | (l.u_roulette[j] < q);
        beta *= roulette ? 1.0f / q : 1.0f;  // times 1 is the same bits
        l.alive[j] = survived & !(max_component(beta) <= 0.0f);
        l.beta.set(j, beta);
        l.origin.set(j, offset_origin(p, ng, offset, wo));
        l.dir.set(j, wo);
    }
}

}  // namespace aliquot
