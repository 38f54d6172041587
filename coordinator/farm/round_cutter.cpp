#include "round_cutter.h"

#include <algorithm>
#include <iterator>
#include <optional>

#include "bands.h"

namespace aliquot {

uint32_t job_tile_side(double mean_spp) {
    uint32_t side = 128;
    while (side > kMinAutoTile && double(side) * side * mean_spp > double(kJobSamples))
        side /= 2;
    return side;
}

namespace {

std::optional<SampleJob> job_for(const PixelRect& rect, const Round& round,
                                 const Accumulator& merged, SampleJob job) {
    job.rect = rect;
    job.counts.resize(rect.size());
    job.first_sample.resize(rect.size());
    uint64_t any = 0;
    const uint32_t w = merged.width();
    size_t k = 0;
    for (uint32_t y = rect.y; y < rect.y + rect.height; ++y) {
        const size_t row = size_t(y) * w + rect.x;
        for (uint32_t x = 0; x < rect.width; ++x, ++k) {
            job.counts[k] = round.spp[row + x];
            job.first_sample[k] = merged.samples(row + x);
            any += round.spp[row + x];
        }
    }
    if (!any) return std::nullopt;
    return job;
}

// The jobs of `rects` that hold samples, in the rects' order; the rects are cut on the
// band pool's threads, each into its own slot, rect k into spare[k]'s vectors when there
// is one.
std::vector<SampleJob> jobs_for(const std::vector<PixelRect>& rects, const Round& round,
                                const Accumulator& merged,
                                std::vector<SampleJob>& spare) {
    std::vector<std::optional<SampleJob>> cut(rects.size());
    // A band of 16 tiles is 16 K pixels at the smallest automatic tile.
    for_each_band(rects.size(), 16, [&](size_t, size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k)
            cut[k] = job_for(rects[k], round, merged,
                             k < spare.size() ? std::move(spare[k]) : SampleJob{});
    });
    spare.erase(spare.begin(), spare.begin() + std::min(spare.size(), rects.size()));
    std::vector<SampleJob> jobs;
    jobs.reserve(rects.size());
    for (std::optional<SampleJob>& job : cut)
        if (job) jobs.push_back(std::move(*job));
    return jobs;
}

size_t tile_count(uint32_t w, uint32_t h, uint32_t tile) {
    return size_t((w + tile - 1) / tile) * ((h + tile - 1) / tile);
}

}  // namespace

std::vector<SampleJob> cut_round(const Round& round, const Accumulator& merged,
                                 uint32_t tile, std::vector<SampleJob> spare) {
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

    std::vector<SampleJob> jobs = jobs_for(tiles, round, merged, spare);
    if (tile < 2 * kMinAutoTile) return jobs;

    // A round ends when its last job does: whoever finishes early waits. Jobs are issued
    // in order, so the last quarter is cut into quadrants and the wait shrinks to a
    // quadrant's work, without making every job small (each costs a lease and a result
    // message).
    const size_t whole = jobs.size() - jobs.size() / 4;
    std::vector<SampleJob> tail(std::make_move_iterator(jobs.begin() + whole),
                                std::make_move_iterator(jobs.end()));
    jobs.resize(whole);
    std::vector<PixelRect> quadrants;
    for (const SampleJob& big : tail) {
        const PixelRect& r = big.rect;
        const uint32_t hw = (r.width + 1) / 2, hh = (r.height + 1) / 2;
        for (const PixelRect& q :
             {PixelRect{r.x, r.y, hw, hh}, PixelRect{r.x + hw, r.y, r.width - hw, hh},
              PixelRect{r.x, r.y + hh, hw, r.height - hh},
              PixelRect{r.x + hw, r.y + hh, r.width - hw, r.height - hh}}) {
            if (q.width == 0 || q.height == 0) continue;
            quadrants.push_back(q);
        }
    }
    // The quadrants take over the spares left and the big jobs they replace.
    std::move(tail.begin(), tail.end(), std::back_inserter(spare));
    for (SampleJob& job : jobs_for(quadrants, round, merged, spare))
        jobs.push_back(std::move(job));
    return jobs;
}

}  // namespace aliquot
