// Cutting a round into sample jobs: square tiles, each pixel's samples continuing from
// the number it already has, so sample indices never repeat across rounds.
#pragma once

#include <algorithm>
#include <vector>

#include "accumulator.h"
#include "strategy.h"

namespace aliquot {

// Tiles of `tile` x `tile` pixels (smaller at the edges); tiles with no samples are
// skipped, and the others cut down to the cells (kCellSide) that hold samples, so that a
// round that refines part of the image merges no more of it than it must. With tile 0 the
// side follows the round's mean spp (see job_tile_side), halved while the round would
// have fewer jobs than asked (round_tiles' min_jobs). Jobs are in issue order; the last
// quarter of the tiles is cut into quadrants so that the round's end waits on small jobs.
//
// Every rectangle is cut on the grid of cells the tracer batches by (kCellSide in
// sample_job.h), so that how a round is cut never changes a bit of the image: an explicit
// `tile` is rounded up to a multiple of kCellSide (automatic tiles are powers of two of
// at least 16 already), and a tile is halved into quadrants at the cell boundary at or
// after its middle (tiles from 32 up are halved; a quadrant is at least a cell unless
// the image's edge clips it).
inline constexpr uint32_t kMinAutoTile = 16;
inline constexpr size_t kMinJobsPerRound = 16;
inline constexpr uint64_t kJobSamples = uint64_t(1) << 18;

// Every job of a round at once (the tests', the studies' and round_digest's way; the
// farm cuts each job when it is first leased, handing cut_job a spent job's vectors).
std::vector<SampleJob> cut_round(const Round& round, const Accumulator& merged,
                                 uint32_t tile = 0);

// cut_round in two steps. The rectangles of the round's jobs, in issue order (one pass
// over the round's counts)...
// With automatic tiles (0), tiles are halved (down to kMinAutoTile) while the round
// has fewer than `min_jobs` jobs: the farm asks for two a live worker core
// (min_jobs_for_cores), so that no core idles through a round for want of a job.
std::vector<PixelRect> round_tiles(const std::vector<uint32_t>& spp, uint32_t width,
                                   uint32_t height, uint32_t tile = 0,
                                   size_t min_jobs = kMinJobsPerRound);
inline std::vector<PixelRect> round_tiles(const Round& round, uint32_t width,
                                          uint32_t height, uint32_t tile = 0,
                                          size_t min_jobs = kMinJobsPerRound) {
    return round_tiles(round.spp, width, height, tile, min_jobs);
}
// Jobs a round should have for a farm of `cores` live worker cores: two each (one traced,
// one waiting), and never fewer than kMinJobsPerRound.
inline size_t min_jobs_for_cores(size_t cores) {
    return std::max(kMinJobsPerRound, 2 * cores);
}
// ...and one job, its counts and first sample indices. The farm cuts each job when it is
// first leased, not all at the round's end: the jobs of a round cover disjoint pixels, so
// until a job merges no other job changes what its pixels have, and it is the job cut at
// the round's end. `spare`'s vectors (a spent job's) are reused: their pages are already
// the process's, where fresh ones were most of cutting's time at 1920x1080.
SampleJob cut_job(const PixelRect& rect, const std::vector<uint32_t>& spp,
                  const Accumulator& merged, SampleJob spare = {});
inline SampleJob cut_job(const PixelRect& rect, const Round& round,
                         const Accumulator& merged, SampleJob spare = {}) {
    return cut_job(rect, round.spp, merged, std::move(spare));
}
// A job of the round after the one out, cut while the round out is still merging
// (render_session.h, "two rounds out"): each pixel's first sample is the one the round
// out leaves it, whether the job that traces it there has merged or is among `unmerged`
// (the round out's jobs not merged yet, each cut). The job cut once the round out has
// merged is the same.
SampleJob cut_job_after(const PixelRect& rect, const std::vector<uint32_t>& spp,
                        const Accumulator& merged,
                        const std::vector<const SampleJob*>& unmerged,
                        SampleJob spare = {});

// Tile side for a round of `mean_spp` samples per pixel: the largest power of two whose
// tile holds at most kJobSamples (about 0.1 s of one worker thread on the Cornell box),
// so a job's fixed cost (a lease, a result message and its merge: about a millisecond of
// CPU, coordinator and worker together, docs/PERFORMANCE.md) stays near 1 % of its
// tracing; at least kMinAutoTile; at most 128x128 pixels, so a result message stays near
// 1 MiB, far below gRPC's 4 MiB. Which job a pixel's samples travel in never changes
// their bytes.
uint32_t job_tile_side(double mean_spp);

}  // namespace aliquot
