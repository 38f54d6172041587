#include "round_cutter.h"

#include <algorithm>

namespace aliquot {

uint32_t job_tile_side(double mean_spp) {
    if (mean_spp >= 32) return 32;
    if (mean_spp >= 8) return 64;
    return 128;
}

std::vector<SampleJob> cut_round(const Round& round, const Accumulator& merged, uint32_t tile) {
    std::vector<SampleJob> jobs;
    const uint32_t w = merged.width(), h = merged.height();
    if (tile == 0) {
        // Mean over the pixels that get samples, so a round that refines a small area is
        // cut by the density it actually has there.
        size_t active = 0;
        for (uint32_t s : round.spp) active += s > 0;
        tile = job_tile_side(active ? double(round.total()) / double(active) : 1.0);
    }
    for (uint32_t y0 = 0; y0 < h; y0 += tile) {
        for (uint32_t x0 = 0; x0 < w; x0 += tile) {
            SampleJob job;
            job.rect = {x0, y0, std::min(tile, w - x0), std::min(tile, h - y0)};
            job.counts.reserve(job.rect.size());
            job.first_sample.reserve(job.rect.size());
            uint64_t any = 0;
            for (uint32_t y = y0; y < y0 + job.rect.height; ++y) {
                for (uint32_t x = x0; x < x0 + job.rect.width; ++x) {
                    const size_t i = size_t(y) * w + x;
                    job.counts.push_back(round.spp[i]);
                    job.first_sample.push_back(merged.samples(i));
                    any += round.spp[i];
                }
            }
            if (any) jobs.push_back(std::move(job));
        }
    }
    return jobs;
}

}  // namespace aliquot
