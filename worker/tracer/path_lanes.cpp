#include "path_lanes.h"

#include "shading.h"
#include "simd_clones.h"
#include "warp.h"

namespace aliquot {

// Every lane steps a copy of its generator; the lanes that draw keep the step. (One loop
// over all lanes, as 64-bit multiplies and rotates vectorise where branches would not.)
ALIQUOT_SIMD_CLONES void draw_diffuse_uniforms(PathLanes& l, int count, bool light) {
    for (int i = 0; i < count; ++i) {
        uint64_t state = l.rng_state[i];
        const uint64_t inc = l.rng_inc[i];
        const bool diffuse = l.diffuse[i] != 0;
        const bool lit = diffuse & light;
        const bool roulette = diffuse & (l.roulette[i] != 0);
        const auto draw = [&](bool taken) {
            uint64_t stepped = state;
            const float u = unit_float(pcg32_step(stepped, inc));
            state = taken ? stepped : state;
            return u;
        };
        l.u_select[i] = draw(lit);
        l.light_u1[i] = draw(lit);
        l.light_u2[i] = draw(lit);
        l.u1[i] = draw(diffuse);
        l.u2[i] = draw(diffuse);
        l.u_roulette[i] = draw(roulette);
        l.rng_state[i] = state;
    }
}

// The count of cdf entries at most u_select, as LightSampler::pick_index counts it,
// a cdf entry at a time over all lanes; then each triangle's fields into the lanes that
// picked it, a triangle at a time.
ALIQUOT_SIMD_CLONES void pick_few_lights(PathLanes& l, int count, const Emitter* emitters,
                                         const float* cdf, int n) {
    int32_t picked[PathLanes::kMax];
    for (int i = 0; i < count; ++i) picked[i] = 0;
    for (int k = 0; k + 1 < n; ++k) {
        const float c = cdf[k];
        for (int i = 0; i < count; ++i) picked[i] += c <= l.u_select[i];
    }
    for (int k = 0; k < n; ++k) {
        const Emitter e = emitters[k];
        for (int i = 0; i < count; ++i) {
            const bool take = picked[i] == k;
            l.light_p0.set(i, select(take, e.p0, l.light_p0.get(i)));
            l.light_e1.set(i, select(take, e.e1, l.light_e1.get(i)));
            l.light_e2.set(i, select(take, e.e2, l.light_e2.get(i)));
            l.light_normal.set(i, select(take, e.normal, l.light_normal.get(i)));
            l.light_radiance.set(i, select(take, e.radiance, l.light_radiance.get(i)));
            l.light_pdf[i] = take ? e.pdf_area : l.light_pdf[i];
        }
    }
}

// The loop body is one-path shading written without branches: what a path would skip
// (the shadow ray when the light faces away, roulette before the fifth vertex, a lane
// that is not diffuse) is computed anyway and selected away, so the compiler can run
// lanes side by side. That changes no result: each lane's operations are its own path's.
// Cloned for wider vectors (simd_clones.h): more paths an instruction.
ALIQUOT_SIMD_CLONES void shade_diffuse(PathLanes& l, int count) {
    for (int i = 0; i < count; ++i) {
        const bool diffuse = l.diffuse[i] != 0;
        const Vec3 d = l.d.get(i), ng = l.ng.get(i);
        const Vec3 p = l.o.get(i) + d * l.t[i];
        const Vec3 n = ng * (dot(d, ng) < 0 ? 1.0f : -1.0f);  // facing the incoming ray
        const Vec3 reflectance = l.reflectance.get(i);
        Vec3 beta = l.beta.get(i);
        const float offset = offset_scale(p);

        // Next-event estimation: a uniform point on the picked triangle (square-root
        // parameterisation), weighted against the bounce by the power heuristic.
        const float su = std::sqrt(l.light_u1[i]);
        const float b1 = 1.0f - su, b2 = l.light_u2[i] * su;
        const Vec3 on_light =
            l.light_p0.get(i) + l.light_e1.get(i) * b1 + l.light_e2.get(i) * b2;
        Vec3 to_light = on_light - p;
        const float dist2 = dot(to_light, to_light);
        const float dist = std::sqrt(dist2);
        to_light = to_light / dist;
        const float cos_light = -dot(to_light, l.light_normal.get(i));
        const float cos_surf = dot(to_light, n);
        const float pdf_area = l.light_pdf[i];
        l.shadow[i] = diffuse & (cos_light > 0) & (cos_surf > 0) & (pdf_area > 0);
        l.shadow_origin.set(i, offset_origin(p, ng, offset, to_light));
        l.shadow_dir.set(i, to_light);
        // Stop short of the light so its own surface does not occlude.
        l.shadow_tmax[i] = dist * (1.0f - 1e-3f);
        const float light_pdf = pdf_area * dist2 / cos_light;
        const float w = power_heuristic(light_pdf, cos_surf * kInvPi);
        l.shadow_L.set(i, beta * reflectance * l.light_radiance.get(i) *
                              (kInvPi * cos_surf * w / light_pdf));

        // The bounce: f * cos / pdf of a Lambertian lobe is its reflectance.
        const Vec3 wo = cosine_hemisphere(n, l.u1[i], l.u2[i]);
        const float bsdf_pdf = std::max(dot(wo, n), 0.0f) * kInvPi;
        Vec3 next_beta = beta * reflectance;

        const bool roulette = l.roulette[i] != 0;
        const float q = survival(next_beta, l.eta[i]);
        const bool survived = !roulette | (l.u_roulette[i] < q);
        next_beta *= roulette ? 1.0f / q : 1.0f;  // times 1 is the same bits
        l.alive[i] = survived & !(max_component(next_beta) <= 0.0f);

        // Other lanes keep theirs: selects of whole lanes, which the loop stores back.
        l.o.set(i, select(diffuse, offset_origin(p, ng, offset, wo), l.o.get(i)));
        l.d.set(i, select(diffuse, wo, d));
        l.beta.set(i, select(diffuse, next_beta, beta));
        l.prev_bsdf_pdf[i] = diffuse ? bsdf_pdf : l.prev_bsdf_pdf[i];
    }
}

}  // namespace aliquot
