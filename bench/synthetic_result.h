// A valid result for a leased job without tracing: what the coordinator benches merge.
// Each pixel's radiance and noise vary smoothly over the image, so that adaptive methods
// see different variances per pixel and do not all stop (or all continue) together.
//
// The simulated workers run on the coordinator's own cores, so what they spend making a
// result is taken from the coordinator: the pattern is therefore made once per image size
// (per thread, so no lock is shared): radiance is 0.2 + 0.6 u v and noise 0.05 +
// 0.5 sin²(6u) cos²(4v), separable into a table per column and per row, and 1/√n comes
// from a table for the counts a job has. A pixel then costs a few multiplies (the sin,
// cos and pow of every pixel were ~20 % of farm_scale's CPU).
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "lease.h"
#include "sample_job.h"

namespace aliquot::bench {

namespace detail {

// One image size's pattern: per column u and sin²(6u), per row v and cos²(4v).
struct SyntheticPattern {
    uint32_t width = 0, height = 0;
    std::vector<double> u, sin2, v, cos2;

    void make(uint32_t w, uint32_t h) {
        width = w;
        height = h;
        u.resize(w);
        sin2.resize(w);
        v.resize(h);
        cos2.resize(h);
        for (uint32_t x = 0; x < w; ++x) {
            u[x] = double(x) / w;
            sin2[x] = std::sin(6.0 * u[x]) * std::sin(6.0 * u[x]);
        }
        for (uint32_t y = 0; y < h; ++y) {
            v[y] = double(y) / h;
            cos2[y] = std::cos(4.0 * v[y]) * std::cos(4.0 * v[y]);
        }
    }
};

// 1/√max(n, 1) for the counts jobs mostly have; larger counts compute it.
inline double inverse_sqrt_count(uint32_t n) {
    static const std::vector<double> table = [] {
        std::vector<double> t(4096);
        for (size_t k = 0; k < t.size(); ++k)
            t[k] = 1 / std::sqrt(std::max(double(k), 1.0));
        return t;
    }();
    return n < table.size() ? table[n] : 1 / std::sqrt(double(n));
}

}  // namespace detail

inline SampleJobResult synthetic_result(const LeaseGrant& grant) {
    thread_local detail::SyntheticPattern pattern;
    if (pattern.width != grant.geometry.width || pattern.height != grant.geometry.height)
        pattern.make(grant.geometry.width, grant.geometry.height);
    SampleJobResult r;
    r.rect = grant.job.rect;
    r.pixels.reserve(r.rect.size());  // each pixel written once, not zeroed first
    const uint32_t* count = grant.job.counts.data();
    for (uint32_t y = r.rect.y; y < r.rect.y + r.rect.height; ++y) {
        const double v = pattern.v[y], cos2 = pattern.cos2[y];
        for (uint32_t x = r.rect.x; x < r.rect.x + r.rect.width; ++x, ++count) {
            PixelSums& p = r.pixels.emplace_back();
            const uint32_t samples = *count;
            if (samples == 0) continue;  // untraced: zero sums
            const double radiance = 0.2 + 0.6 * pattern.u[x] * v;
            const double noise = 0.05 + 0.5 * pattern.sin2[x] * cos2;
            const double n = double(samples);
            const double half = 0.5 * n * radiance;
            const double spread = noise * detail::inverse_sqrt_count(samples);
            const double even = half * (1 + spread), odd = half * (1 - spread);
            p.even[0] = p.even[1] = p.even[2] = even;
            p.odd[0] = p.odd[1] = p.odd[2] = odd;
            p.sum_sq_luminance = n * radiance * radiance * (1 + noise * noise);
            p.samples = samples;
            p.rays = 6 * uint64_t(samples);
        }
    }
    return r;
}

}  // namespace aliquot::bench
