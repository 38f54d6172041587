// A valid result for a leased job without tracing: what the coordinator benches merge.
// Each pixel's radiance and noise vary smoothly over the image, so that adaptive methods
// see different variances per pixel and do not all stop (or all continue) together.
#pragma once

#include <cmath>

#include "lease.h"
#include "sample_job.h"

namespace aliquot::bench {

inline SampleJobResult synthetic_result(const LeaseGrant& grant) {
    SampleJobResult r;
    r.rect = grant.job.rect;
    r.pixels.resize(r.rect.size());
    for (uint32_t y = 0; y < r.rect.height; ++y)
        for (uint32_t x = 0; x < r.rect.width; ++x) {
            const size_t i = size_t(y) * r.rect.width + x;
            const double u = double(r.rect.x + x) / grant.geometry.width;
            const double v = double(r.rect.y + y) / grant.geometry.height;
            const double radiance = 0.2 + 0.6 * u * v;
            const double noise =
                0.05 + 0.5 * std::pow(std::sin(6.0 * u) * std::cos(4.0 * v), 2);
            PixelSums& p = r.pixels[i];
            p.samples = grant.job.counts[i];
            const double n = double(p.samples);
            const double half = 0.5 * n;
            for (int c = 0; c < 3; ++c) {
                p.even[c] = half * radiance * (1 + noise / std::sqrt(std::max(n, 1.0)));
                p.odd[c] = half * radiance * (1 - noise / std::sqrt(std::max(n, 1.0)));
            }
            p.sum_sq_luminance = n * radiance * radiance * (1 + noise * noise);
            p.rays = 6 * p.samples;
        }
    return r;
}

}  // namespace aliquot::bench
