// Bands: the coordinator's data-parallel per-pixel passes (a round end's error estimate,
// the strategies' plans, cutting jobs, the checkpoint copy) spread over its hardware
// threads. The items are cut into bands of a size the caller fixes, never one that
// depends on the number of threads, and each band writes only its own outputs; a caller
// that reduces combines per-band results in band order. So a pass gives the same bits
// with one thread or many.
#pragma once

#include <cstddef>
#include <functional>

namespace aliquot {

// Pixels in one band of a per-pixel pass: enough that a band's work (tens of
// microseconds) dwarfs handing it out, few enough that a 1920x1080 image has ~30 of
// them to share. Part of the results' definition wherever bands are reduced: do not tie
// it to the machine.
constexpr size_t kBandPixels = size_t(1) << 16;

// Number of bands of `band` items that cover `items`.
inline size_t band_count(size_t items, size_t band) {
    return band ? (items + band - 1) / band : 0;
}

// Calls fn(index, begin, end) once for each band [begin, end) = [index * band,
// min(items, (index + 1) * band)), on the calling thread and the pool's. Returns when
// every band is done; rethrows the first exception a band threw. A call made while
// another is running (another render's round end, or a pass inside a pass) runs its
// bands on its own thread: the results are the same, only slower.
void for_each_band(size_t items, size_t band,
                   const std::function<void(size_t index, size_t begin, size_t end)>& fn);

// From now on, passes started on the calling thread run on it alone, as a pass inside a
// pass does: for a background thread (the record writer's, at a low priority), whose
// passes must not take the pool from a round end, nor start the pool's threads, which
// would inherit its priority.
void keep_passes_on_this_thread();

// Threads that run bands, the caller's included; the machine's hardware threads unless
// set. set_band_threads(1) runs everything on the caller (tests compare it with more).
unsigned band_threads();
void set_band_threads(unsigned threads);

// CPU seconds the pool's own threads (not the callers) have spent running bands since
// the process started: added to a round end's CPU time, which the calling thread's
// clock alone would under-count.
double band_pool_cpu_seconds();

}  // namespace aliquot
