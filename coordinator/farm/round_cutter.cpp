#include "round_cutter.h"

#include <algorithm>
#include <iterator>
#include <optional>

namespace aliquot {

uint32_t job_tile_side(double mean_spp) {
    if (mean_spp >= 32) return 32;
    if (mean_spp >= 8) return 64;
    return 128;
}

namespace {

std::optional<SampleJob> job_for(const PixelRect& rect, const Round& round,
                                 const Accumulator& merged) {
    SampleJob job;
    job.rect = rect;
    job.counts.reserve(rect.size());
    job.first_sample.reserve(rect.size());
    uint64_t any = 0;
    const uint32_t w = merged.width();
    for (uint32_t y = rect.y; y < rect.y + rect.height; ++y) {
        for (uint32_t x = rect.x; x < rect.x + rect.width; ++x) {
            const size_t i = size_t(y) * w + x;
            job.counts.push_back(round.spp[i]);
            job.first_sample.push_back(merged.samples(i));
            any += round.spp[i];
        }
    }
    if (!any) return std::nullopt;
    return job;
}

size_t tile_count(uint32_t w, uint32_t h, uint32_t tile) {
    return size_t((w + tile - 1) / tile) * ((h + tile - 1) / tile);
}

}  // namespace

std::vector<SampleJob> cut_round(const Round& round, const Accumulator& merged,
                                 uint32_t tile) {
    const uint32_t w = merged.width(), h = merged.height();
    if (tile == 0) {
        // Mean over the pixels that get samples, so a round that refines a small area is
        // cut by the density it actually has there.
        size_t active = 0;
        for (uint32_t s : round.spp) active += s > 0;
        tile = job_tile_side(active ? double(round.total()) / double(active) : 1.0);
        // Enough jobs to keep several workers' threads busy even on a small image.
        while (tile > kMinAutoTile && tile_count(w, h, tile) < kMinJobsPerRound)
            tile /= 2;
    }
    std::vector<PixelRect> tiles;
    for (uint32_t y0 = 0; y0 < h; y0 += tile)
        for (uint32_t x0 = 0; x0 < w; x0 += tile)
            tiles.push_back({x0, y0, std::min(tile, w - x0), std::min(tile, h - y0)});

    std::vector<SampleJob> jobs;
    for (const PixelRect& rect : tiles)
        if (auto job = job_for(rect, round, merged)) jobs.push_back(std::move(*job));
    if (tile < 2 * kMinAutoTile) return jobs;

    // A round ends when its last job does: whoever finishes early waits. Jobs are issued
    // in order, so the last quarter is cut into quadrants and the wait shrinks to a
    // quadrant's work, without making every job small (each costs a lease and a result
    // message).
    const size_t whole = jobs.size() - jobs.size() / 4;
    std::vector<SampleJob> tail(std::make_move_iterator(jobs.begin() + whole),
                                std::make_move_iterator(jobs.end()));
    jobs.resize(whole);
    for (const SampleJob& big : tail) {
        const PixelRect& r = big.rect;
        const uint32_t hw = (r.width + 1) / 2, hh = (r.height + 1) / 2;
        for (const PixelRect& q :
             {PixelRect{r.x, r.y, hw, hh}, PixelRect{r.x + hw, r.y, r.width - hw, hh},
              PixelRect{r.x, r.y + hh, hw, r.height - hh},
              PixelRect{r.x + hw, r.y + hh, r.width - hw, r.height - hh}}) {
            if (q.width == 0 || q.height == 0) continue;
            if (auto job = job_for(q, round, merged)) jobs.push_back(std::move(*job));
        }
    }
    return jobs;
}

}  // namespace aliquot
