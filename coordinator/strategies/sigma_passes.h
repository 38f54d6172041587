// The passes over the image that optimal's sigma is estimated by (optimal_strategy.cpp),
// each in bands of rows or pixels on the pool's threads (bands.h), the same bits with
// one thread or many.
#pragma once

#include <cstdint>
#include <vector>

namespace aliquot::sigma_passes {

// Protection against sigma under-estimated at low spp. A pixel's variance is never taken
// below half the median of its 3x3 neighbourhood: variance is spatially coherent (a
// caustic or a light's edge covers several pixels), so a pixel whose few samples happened
// to agree inside a noisy region is probably as noisy as the region; the median rather
// than the mean, so that one isolated firefly does not make its eight neighbours look
// noisy. Nor below 1/256 of the image's median variance: a pixel estimated at zero still
// gets (1/256)^(1/3) ≈ 0.16 of a typical pixel's share and keeps being re-estimated as
// its count grows, instead of staying at min_spp for ever. Over-estimates cost little:
// the error is flat near the optimum.
inline constexpr double kNeighbourhoodFactor = 0.5;
inline constexpr double kImageFactor = 1.0 / 256;

// sigma_i = sqrt(max(v_i, kNeighbourhoodFactor * (v's 3x3 median around i), least)),
// written into `out` (w x h pixels, row by row).
void sigma_from_neighbourhood(const std::vector<double>& v, uint32_t w, uint32_t h,
                              double least, std::vector<double>& out);

// The mean of v over the (2r+1)^2 window around each pixel (clipped at the image's
// edges), from a summed-area table: O(pixels) whatever r.
std::vector<double> box_mean(const std::vector<double>& v, uint32_t w, uint32_t h,
                             uint32_t r);

// The largest sigma_self_out: a window of at most 7x7, so each pixel's neighbours are
// summed one by one (at most 48 additions, no sums that slide or differences).
inline constexpr uint32_t kMaxSelfOutRadius = 3;

// The mean of v over the (2r+1)^2 - 1 pixels around each pixel, the pixel itself left
// out (clipped at the image's edges; v itself for a 1x1 image), written into `out`
// (w x h pixels, row by row; not v). r from 1 to kMaxSelfOutRadius. For values that are
// finite and >= 0 the means are >= 0, at worst +inf, never NaN.
void neighbours_mean(const std::vector<double>& v, uint32_t w, uint32_t h, uint32_t r,
                     std::vector<double>& out);

// The element of rank n/2 of v (what nth_element on a copy gives), for values that are
// finite and >= +0. `counts` and `candidates` are kept by the caller from one plan to the
// next.
double median_value(const std::vector<double>& v,
                    std::vector<std::vector<uint32_t>>& counts,
                    std::vector<double>& candidates);

}  // namespace aliquot::sigma_passes
