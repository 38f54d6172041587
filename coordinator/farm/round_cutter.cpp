#include "round_cutter.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <utility>

#include "bands.h"

namespace aliquot {

uint32_t job_tile_side(double mean_spp) {
    uint32_t side = 128;
    while (side > kMinAutoTile && double(side) * side * mean_spp > double(kJobSamples))
        side /= 2;
    return side;
}

SampleJob cut_job(const PixelRect& rect, const std::vector<uint32_t>& spp,
                  const Accumulator& merged, SampleJob job) {
    job.rect = rect;
    job.counts.resize(rect.size());
    job.first_sample.resize(rect.size());
    // A row at a time through plain pointers and a width held in a local: the stores
    // could otherwise alias the rectangle and the vectors, and the loop, reloading them
    // every pixel, did not vectorise (~3 % of farm_scale's CPU for dammertz at 1080p).
    const uint32_t w = merged.width(), width = rect.width;
    uint32_t* counts = job.counts.data();
    uint64_t* first = job.first_sample.data();
    for (uint32_t y = 0; y < rect.height; ++y) {
        const size_t row = size_t(rect.y + y) * w + rect.x;
        const uint32_t* from = spp.data() + row;
        for (uint32_t x = 0; x < width; ++x) counts[x] = from[x];
        for (uint32_t x = 0; x < width; ++x) first[x] = merged.samples(row + x);
        counts += width;
        first += width;
    }
    return job;
}

SampleJob cut_job_after(const PixelRect& rect, const std::vector<uint32_t>& spp,
                        const Accumulator& merged,
                        const std::vector<const SampleJob*>& unmerged, SampleJob spare) {
    SampleJob job = cut_job(rect, spp, merged, std::move(spare));
    // Where an unmerged job of the round out overlaps, its samples are still to come.
    for (const SampleJob* out : unmerged) {
        const PixelRect& o = out->rect;
        const uint32_t x0 = std::max(rect.x, o.x), y0 = std::max(rect.y, o.y);
        const uint32_t x1 = std::min(rect.x + rect.width, o.x + o.width);
        const uint32_t y1 = std::min(rect.y + rect.height, o.y + o.height);
        for (uint32_t y = y0; y < y1; ++y)
            for (uint32_t x = x0; x < x1; ++x)
                job.first_sample[size_t(y - rect.y) * rect.width + (x - rect.x)] +=
                    out->counts[size_t(y - o.y) * o.width + (x - o.x)];
    }
    return job;
}

namespace {

size_t tile_count(uint32_t w, uint32_t h, uint32_t tile) {
    return size_t((w + tile - 1) / tile) * ((h + tile - 1) / tile);
}

// Where a tile's side is halved: at the first cell boundary at or after its middle, so
// that a quadrant holds whole cells (the whole side when that boundary is its end).
uint32_t half_on_cells(uint32_t side) {
    const uint32_t half = (side + 1) / 2;
    return std::min(side, (half + kCellSide - 1) / kCellSide * kCellSide);
}

// The quadrants of a tile, as the tail of a round is cut: top left, top right, bottom
// left, bottom right (some empty when a side is a cell or less).
std::array<PixelRect, 4> quadrants_of(const PixelRect& r) {
    const uint32_t hw = half_on_cells(r.width), hh = half_on_cells(r.height);
    return {PixelRect{r.x, r.y, hw, hh}, PixelRect{r.x + hw, r.y, r.width - hw, hh},
            PixelRect{r.x, r.y + hh, hw, r.height - hh},
            PixelRect{r.x + hw, r.y + hh, r.width - hw, r.height - hh}};
}

// The pixels of a quadrant that hold samples: the bounds of their columns and rows (empty
// while x0 >= x1).
struct Extent {
    uint32_t x0 = UINT32_MAX, x1 = 0, y0 = UINT32_MAX, y1 = 0;
    bool empty() const { return x0 >= x1; }
    // Row y's pixels [a, b) of `row`: the first and last with samples, found from either
    // end (at once in a row that is all samples; the whole span in one without).
    void add_row(const uint32_t* row, uint32_t a, uint32_t b, uint32_t y) {
        uint32_t first = a;
        while (first < b && row[first] == 0) ++first;
        if (first == b) return;
        uint32_t last = b - 1;
        while (row[last] == 0) --last;
        x0 = std::min(x0, first);
        x1 = std::max(x1, last + 1);
        y0 = std::min(y0, y);
        y1 = std::max(y1, y + 1);
    }
    void add(const Extent& e) {
        x0 = std::min(x0, e.x0);
        x1 = std::max(x1, e.x1);
        y0 = std::min(y0, e.y0);
        y1 = std::max(y1, e.y1);
    }
};

// `r` cut down to the cells (kCellSide, on the image's grid) that hold `e`, so that a
// job merges no pixels a round that refines a small part of the image skips, and how a
// round is cut still changes no bit: r's own edges are on the grid or the image's edge.
PixelRect trimmed(const PixelRect& r, const Extent& e) {
    const uint32_t x0 = std::max(r.x, e.x0 / kCellSide * kCellSide);
    const uint32_t y0 = std::max(r.y, e.y0 / kCellSide * kCellSide);
    const uint64_t x1 =
        std::min<uint64_t>(uint64_t(r.x) + r.width,
                           (uint64_t(e.x1) + kCellSide - 1) / kCellSide * kCellSide);
    const uint64_t y1 =
        std::min<uint64_t>(uint64_t(r.y) + r.height,
                           (uint64_t(e.y1) + kCellSide - 1) / kCellSide * kCellSide);
    return {x0, y0, uint32_t(x1 - x0), uint32_t(y1 - y0)};
}

// The jobs of tiles of side `tile`: the tiles that hold samples, each cut down to the
// cells that do, the last quarter of them in quadrants.
std::vector<PixelRect> tiles_of_side(const std::vector<uint32_t>& spp, uint32_t w,
                                     uint32_t h, uint32_t tile) {
    const uint32_t across = (w + tile - 1) / tile, down = (h + tile - 1) / tile;
    const auto rect_of = [&](size_t t) {
        const uint32_t x0 = uint32_t(t % across) * tile, y0 = uint32_t(t / across) * tile;
        return PixelRect{x0, y0, std::min(tile, w - x0), std::min(tile, h - y0)};
    };
    // Where each quadrant of each tile holds samples, from one pass over the counts in
    // bands of tile rows (a tile's rows are all in one band; bounds are the same in any
    // order).
    std::vector<Extent> holds(size_t(across) * down * 4);
    const size_t rows_per_band = std::max<size_t>(1, kBandPixels / (size_t(tile) * w));
    for_each_band(down, rows_per_band, [&](size_t, size_t row0, size_t row1) {
        for (size_t ty = row0; ty < row1; ++ty) {
            const uint32_t y0 = uint32_t(ty) * tile, th = std::min(tile, h - y0);
            for (uint32_t y = y0; y < y0 + th; ++y) {
                const uint32_t* row = &spp[size_t(y) * w];
                const size_t lower = y - y0 < half_on_cells(th) ? 0 : 2;
                for (uint32_t tx = 0; tx < across; ++tx) {
                    const uint32_t x0 = tx * tile, tw = std::min(tile, w - x0);
                    const uint32_t mid = x0 + half_on_cells(tw);
                    Extent* q = &holds[(ty * across + tx) * 4 + lower];
                    q[0].add_row(row, x0, mid, y);
                    q[1].add_row(row, mid, x0 + tw, y);
                }
            }
        }
    });
    std::vector<size_t> kept;  // the tiles with samples, row by row
    for (size_t t = 0; t < size_t(across) * down; ++t)
        if (!holds[4 * t].empty() || !holds[4 * t + 1].empty() ||
            !holds[4 * t + 2].empty() || !holds[4 * t + 3].empty())
            kept.push_back(t);
    std::vector<PixelRect> rects;
    // A round ends when its last job does: whoever finishes early waits. Jobs are issued
    // in order, so the last quarter is cut into quadrants and the wait shrinks to a
    // quadrant's work, without making every job small (each costs a lease and a result
    // message).
    const size_t whole =
        tile < 2 * kMinAutoTile ? kept.size() : kept.size() - kept.size() / 4;
    for (size_t k = 0; k < whole; ++k) {
        Extent all;
        for (int i = 0; i < 4; ++i) all.add(holds[4 * kept[k] + i]);
        rects.push_back(trimmed(rect_of(kept[k]), all));
    }
    for (size_t k = whole; k < kept.size(); ++k) {
        const std::array<PixelRect, 4> q = quadrants_of(rect_of(kept[k]));
        for (int i = 0; i < 4; ++i)
            if (q[i].width > 0 && q[i].height > 0 && !holds[4 * kept[k] + i].empty())
                rects.push_back(trimmed(q[i], holds[4 * kept[k] + i]));
    }
    return rects;
}

}  // namespace

std::vector<PixelRect> round_tiles(const std::vector<uint32_t>& spp, uint32_t w,
                                   uint32_t h, uint32_t tile, size_t min_jobs) {
    const size_t n = size_t(w) * h;
    const bool automatic = tile == 0;
    if (automatic) {
        // Mean over the pixels that get samples, so a round that refines a small area is
        // cut by the density it actually has there.
        std::vector<std::pair<size_t, uint64_t>> band(band_count(n, kBandPixels));
        for_each_band(n, kBandPixels, [&](size_t b, size_t begin, size_t end) {
            size_t active = 0;
            uint64_t total = 0;
            for (size_t i = begin; i < end; ++i) {
                active += spp[i] > 0;
                total += spp[i];
            }
            band[b] = {active, total};
        });
        size_t active = 0;
        uint64_t total = 0;
        for (const auto& [a, t] : band) active += a, total += t;
        tile = job_tile_side(active ? double(total) / double(active) : 1.0);
        // Enough jobs to keep several workers' threads busy even on a small image.
        while (tile > kMinAutoTile && tile_count(w, h, tile) < min_jobs) tile /= 2;
    } else {
        tile = uint32_t(std::min<uint64_t>(
            (uint64_t(tile) + kCellSide - 1) / kCellSide * kCellSide, uint64_t(1) << 31));
    }
    std::vector<PixelRect> rects = tiles_of_side(spp, w, h, tile);
    // A round with fewer jobs than the farm has worker cores leaves some idle from its
    // start, and one with about as many idles most of them through its tail: smaller
    // tiles while there are fewer jobs than asked for (a round that refines a small area
    // skips most tiles, which the count of the image's tiles above cannot see).
    while (automatic && rects.size() < min_jobs && tile > kMinAutoTile) {
        tile /= 2;
        rects = tiles_of_side(spp, w, h, tile);
    }
    return rects;
}

std::vector<SampleJob> cut_round(const Round& round, const Accumulator& merged,
                                 uint32_t tile) {
    const std::vector<PixelRect> rects =
        round_tiles(round, merged.width(), merged.height(), tile);
    std::vector<SampleJob> jobs(rects.size());
    // A band of 16 jobs is 16 K pixels at the smallest automatic tile.
    for_each_band(rects.size(), 16, [&](size_t, size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k) jobs[k] = cut_job(rects[k], round, merged);
    });
    return jobs;
}

}  // namespace aliquot
