#include "sigma_passes.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "bands.h"

namespace aliquot::sigma_passes {

namespace {

// The median of nine values: Paeth's 19 compare-exchanges, the same value selection
// would pick (a median is a value, not a position), at a third of nth_element's cost.
inline double median_of_nine(double p[9]) {
    const auto order = [](double& a, double& b) {
        const double lo = std::min(a, b), hi = std::max(a, b);
        a = lo;
        b = hi;
    };
    order(p[1], p[2]), order(p[4], p[5]), order(p[7], p[8]);
    order(p[0], p[1]), order(p[3], p[4]), order(p[6], p[7]);
    order(p[1], p[2]), order(p[4], p[5]), order(p[7], p[8]);
    order(p[0], p[3]), order(p[5], p[8]), order(p[4], p[7]);
    order(p[3], p[6]), order(p[1], p[4]), order(p[2], p[5]);
    order(p[4], p[7]), order(p[4], p[2]), order(p[6], p[4]);
    order(p[4], p[2]);
    return p[4];
}

// Rows per band of a pass over rows: about kBandPixels pixels.
size_t rows_per_band(uint32_t w) {
    return std::max<size_t>(1, kBandPixels / std::max(w, 1u));
}

}  // namespace

// sigma_i = sqrt(max(v_i, kNeighbourhoodFactor * (v's 3x3 median around i), least)):
// the median and the rest in one pass over rows in bands, without a buffer of medians.
// Inside the image each row's medians are taken by the same compare-exchanges, pixel by
// pixel, in a loop over the row that the compiler vectorises; the clipped windows at the
// edges are selected as before. Written into `out`.
void sigma_from_neighbourhood(const std::vector<double>& v, uint32_t w, uint32_t h,
                              double least, std::vector<double>& out) {
    out.resize(v.size());
    const auto finish = [&](size_t i, double near) {
        out[i] = std::sqrt(std::max({v[i], kNeighbourhoodFactor * near, least}));
    };
    const auto clipped = [&](uint32_t x, uint32_t y) {  // a window of 4 or 6 at an edge
        double window[9];
        int n = 0;
        for (uint32_t yy = y ? y - 1 : 0; yy <= std::min(y + 1, h - 1); ++yy)
            for (uint32_t xx = x ? x - 1 : 0; xx <= std::min(x + 1, w - 1); ++xx)
                window[n++] = v[size_t(yy) * w + xx];
        std::nth_element(window, window + n / 2, window + n);
        return window[n / 2];
    };
    for_each_band(h, rows_per_band(w), [&](size_t, size_t row0, size_t row1) {
        for (uint32_t y = uint32_t(row0); y < row1; ++y) {
            const size_t row = size_t(y) * w;
            if (y == 0 || y + 1 >= h || w < 3) {
                for (uint32_t x = 0; x < w; ++x) finish(row + x, clipped(x, y));
                continue;
            }
            const double* above = &v[row - w];
            const double* mid = &v[row];
            const double* below = &v[row + w];
            double* near = &out[row];  // the medians first, then sigma in place
            for (uint32_t x = 1; x + 1 < w; ++x) {
                double p[9] = {above[x - 1], above[x], above[x + 1],
                               mid[x - 1],   mid[x],   mid[x + 1],
                               below[x - 1], below[x], below[x + 1]};
                near[x] = median_of_nine(p);
            }
            finish(row, clipped(0, y));
            for (uint32_t x = 1; x + 1 < w; ++x) finish(row + x, near[x]);
            finish(row + w - 1, clipped(w - 1, y));
        }
    });
}

std::vector<double> box_mean(const std::vector<double>& v, uint32_t w, uint32_t h,
                             uint32_t r) {
    std::vector<double> sat(size_t(w + 1) * (h + 1), 0.0);
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
            sat[size_t(y + 1) * (w + 1) + x + 1] =
                v[size_t(y) * w + x] + sat[size_t(y) * (w + 1) + x + 1] +
                sat[size_t(y + 1) * (w + 1) + x] - sat[size_t(y) * (w + 1) + x];
    std::vector<double> out(v.size());
    for_each_band(h, rows_per_band(w), [&](size_t, size_t row0, size_t row1) {
        for (uint32_t y = uint32_t(row0); y < row1; ++y) {
            const uint32_t y0 = y > r ? y - r : 0, y1 = std::min(h, y + r + 1);
            for (uint32_t x = 0; x < w; ++x) {
                const uint32_t x0 = x > r ? x - r : 0, x1 = std::min(w, x + r + 1);
                const double sum =
                    sat[size_t(y1) * (w + 1) + x1] - sat[size_t(y0) * (w + 1) + x1] -
                    sat[size_t(y1) * (w + 1) + x0] + sat[size_t(y0) * (w + 1) + x0];
                out[size_t(y) * w + x] = sum / double(size_t(y1 - y0) * (x1 - x0));
            }
        }
    });
    return out;
}

// Leave-one-out: a pixel's own samples must not set its own count (docs/RESULTS.md, "Is
// `optimal` biased low?"). Each band of rows keeps two rows of column sums over the
// window's rows: `beside` with the pixel's row left out, `whole` with it; a pixel's
// neighbours are its own column's `beside` plus the other columns' `whole`. Only
// additions of values >= 0, in an order fixed by the pixel, so the same bits in any band
// or thread, and a firefly's variance is never subtracted from a sum (which would leave
// its rounding behind in a quiet neighbour's mean).
void neighbours_mean(const std::vector<double>& v, uint32_t w, uint32_t h, uint32_t r,
                     std::vector<double>& out) {
    out.resize(v.size());
    for_each_band(h, rows_per_band(w), [&](size_t, size_t row0, size_t row1) {
        std::vector<double> beside(w), whole(w);
        for (uint32_t y = uint32_t(row0); y < row1; ++y) {
            const uint32_t top = y > r ? y - r : 0, bottom = std::min(h, y + r + 1);
            const double* mid = &v[size_t(y) * w];
            std::fill(beside.begin(), beside.end(), 0.0);
            for (uint32_t yy = top; yy < bottom; ++yy) {
                if (yy == y) continue;
                const double* row = &v[size_t(yy) * w];
                for (uint32_t x = 0; x < w; ++x) beside[x] += row[x];
            }
            for (uint32_t x = 0; x < w; ++x) whole[x] = beside[x] + mid[x];
            const double rows = double(bottom - top);
            double* mean = &out[size_t(y) * w];
            const auto clipped = [&](uint32_t x) {
                const uint32_t left = x > r ? x - r : 0, right = std::min(w, x + r + 1);
                double sum = beside[x];
                for (uint32_t xx = left; xx < right; ++xx)
                    if (xx != x) sum += whole[xx];
                const double others = rows * double(right - left) - 1;
                mean[x] = others > 0 ? sum / others : mid[x];
            };
            if (w <= 2 * r) {
                for (uint32_t x = 0; x < w; ++x) clipped(x);
                continue;
            }
            for (uint32_t x = 0; x < r; ++x) clipped(x);
            const double others = rows * double(2 * r + 1) - 1;
            for (uint32_t x = r; x + r < w; ++x) {
                double sum = beside[x];
                for (uint32_t d = 1; d <= r; ++d) sum += whole[x - d] + whole[x + d];
                mean[x] = sum / others;
            }
            for (uint32_t x = w - r; x < w; ++x) clipped(x);
        }
    });
}

// The element of rank n/2 of v (what nth_element on a copy gives), for values that are
// finite and >= +0: their bit patterns sort as the values do, so a histogram of the top
// 16 bits, counted in bands, finds the bucket that holds the rank and selection runs on
// that bucket alone. A median is a value, so the result is the same as sorting's.
// `counts` and `candidates` are kept by the caller from one plan to the next.
double median_value(const std::vector<double>& v,
                    std::vector<std::vector<uint32_t>>& counts,
                    std::vector<double>& candidates) {
    const size_t n = v.size();
    if (n == 0) return 0.0;
    if (n <= kBandPixels) {  // one band: a histogram would cost more
        candidates.assign(v.begin(), v.end());
        std::nth_element(candidates.begin(), candidates.begin() + n / 2,
                         candidates.end());
        return candidates[n / 2];
    }
    const auto bits = [&](size_t i) {
        uint64_t b;
        std::memcpy(&b, &v[i], sizeof b);
        return b;
    };
    constexpr int kShift = 48;
    constexpr size_t kBuckets = size_t(1) << (64 - kShift);
    const size_t bands = band_count(n, kBandPixels);
    counts.resize(bands);
    for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        std::vector<uint32_t>& c = counts[band];
        c.assign(kBuckets, 0);
        for (size_t i = begin; i < end; ++i) ++c[bits(i) >> kShift];
    });
    size_t rank = n / 2, bucket = 0;
    for (;; ++bucket) {
        size_t in_bucket = 0;
        for (const std::vector<uint32_t>& c : counts) in_bucket += c[bucket];
        if (rank < in_bucket) break;
        rank -= in_bucket;
    }
    // The bucket's values, band by band in pixel order.
    std::vector<size_t> offset(bands + 1, 0);
    for (size_t b = 0; b < bands; ++b) offset[b + 1] = offset[b] + counts[b][bucket];
    candidates.resize(offset[bands]);
    for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        size_t k = offset[band];
        for (size_t i = begin; i < end; ++i)
            if ((bits(i) >> kShift) == bucket) candidates[k++] = v[i];
    });
    std::nth_element(candidates.begin(), candidates.begin() + rank, candidates.end());
    return candidates[rank];
}

}  // namespace aliquot::sigma_passes
