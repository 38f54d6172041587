// Error metrics between a test image and a reference (the seed's E, RMSE, relMSE,
// buckets, the image's mean bias).
#include "error_metric.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace aliquot {
namespace {

std::string resolution(const Image& image) {
    return std::to_string(image.width) + "x" + std::to_string(image.height);
}

// Nearest-rank percentile: the smallest value with at least p% of the values at or below
// it, so it is always one of the bucket errors, never an interpolation between two.
double nearest_rank(std::vector<double> values, double p) {
    std::sort(values.begin(), values.end());
    size_t rank = size_t(std::ceil(p / 100.0 * double(values.size())));
    return values[std::clamp<size_t>(rank, 1, values.size()) - 1];
}

// The side of the blocks whose mean differences give the mean bias's standard error: 16
// pixels, halved until the image holds at least kMinBiasBlocks of them (a 16x16 image:
// 4). Fixed in pixels rather than the metric's bucket size, which a study scales with its
// resolution down to 1 pixel: a denoiser spreads a pixel's error over neighbours a fixed
// number of pixels away, so the blocks must stay wider than that whatever the scale.
constexpr uint32_t kBiasBlock = 16;
constexpr uint64_t kMinBiasBlocks = 16;

uint32_t bias_block_side(uint32_t w, uint32_t h) {
    uint32_t s = kBiasBlock;
    while (s > 1 && uint64_t((w + s - 1) / s) * ((h + s - 1) / s) < kMinBiasBlocks)
        s /= 2;
    return s;
}

// mean_bias and its standard error from the pass's sums: `block_diff` holds each block's
// sum of per-pixel differences (A - B averaged over RGB), blocks of side `s` over a w x h
// image. The standard error is the batch means': a block's mean difference varies with
// its pixels' noise however it is correlated inside the block (a denoiser's kernel, a
// caustic's clustered fireflies), and the blocks' means are nearly independent of each
// other. Edge blocks are smaller: with n_k pixels and difference sum D_k, the variance of
// the whole image's mean difference D/N is K/(K-1) * sum_k (D_k - n_k D/N)^2 / N^2 (the
// ratio estimator's; for equal blocks, the variance of the block means over K). From the
// few blocks of a small image that estimate is itself noisy, and a heavy-tailed image's
// rare fireflies make it run low by chance (a 128x128 caustics render at 16 spp: 0.6 %
// from its 64 blocks, 1.5 % from its pixels); where pixels are independent, the
// per-pixel error (`diff_sq_sum`, the sum of the squared per-pixel differences) is the
// better estimate of the same thing. So the error is the larger of the two: never below
// the pixels', and the blocks' wherever neighbours' errors share a sign.
void set_mean_bias(ErrorMetrics& m, const std::vector<double>& block_diff, uint32_t w,
                   uint32_t h, uint32_t s, double ref_sum, double diff_sq_sum) {
    const double pixels = double(w) * h, ref_mean = ref_sum / (3.0 * pixels);
    double diff_sum = 0;
    for (const double d : block_diff) diff_sum += d;
    // A NaN or inf in either image makes the sums so: no bias to tell, not a bias of 0 +-
    // 0 (std::max(0.0, NaN) would have made it one).
    if (!std::isfinite(diff_sum) || !std::isfinite(ref_sum) || !(ref_mean > 0)) {
        m.mean_bias = m.mean_bias_se = std::nan("");
        return;
    }
    const double diff_mean = diff_sum / pixels;
    m.mean_bias = diff_mean / ref_mean;
    const size_t blocks = block_diff.size();
    if (blocks < 2) {  // one block (a 1x1 image) has no spread to measure
        m.mean_bias_se = std::nan("");
        return;
    }
    const uint32_t blocks_x = (w + s - 1) / s;
    double spread = 0;
    for (size_t k = 0; k < blocks; ++k) {
        const uint32_t bx = uint32_t(k % blocks_x), by = uint32_t(k / blocks_x);
        const double n = double(std::min(s, w - bx * s)) * std::min(s, h - by * s);
        const double r = block_diff[k] - n * diff_mean;
        spread += r * r;
    }
    const double block_variance =
        double(blocks) / double(blocks - 1) * spread / (pixels * pixels);
    // Rounding can take the pixels' a hair below 0; both are finite here.
    const double pixel_variance =
        std::max(0.0, (diff_sq_sum - diff_sum * diff_mean) / (pixels - 1)) / pixels;
    m.mean_bias_se = std::sqrt(std::max(block_variance, pixel_variance)) / ref_mean;
}

}  // namespace

bool bias_beyond_noise(const ErrorMetrics& m) {
    return std::abs(m.mean_bias) > 3.0 * m.mean_bias_se;
}

std::string mean_bias_text(const ErrorMetrics& m) {
    // mean_abs is NaN exactly when some pixel's difference is not finite (the sums of
    // finite floats in doubles do not overflow): that, not a black reference, is why.
    if (!std::isfinite(m.mean_abs)) return "– (an image holds NaN or inf)";
    if (std::isnan(m.mean_bias)) return "– (the reference is black)";
    char text[96];
    if (std::isnan(m.mean_bias_se)) {
        std::snprintf(text, sizeof text, "%+.3g %% (no standard error: one block)",
                      100 * m.mean_bias);
        return text;
    }
    std::snprintf(text, sizeof text, "%+.3g %% ± %.2g %%%s", 100 * m.mean_bias,
                  100 * m.mean_bias_se,
                  bias_beyond_noise(m) ? ", beyond 3 SE: biased" : ", within 3 SE");
    return text;
}

ErrorMetrics compare_images(const Image& test, const Image& reference, int bucket_size) {
    if (test.width != reference.width || test.height != reference.height)
        throw ImageMismatch("resolution differs: " + resolution(test) + " vs " +
                            resolution(reference));
    if (bucket_size <= 0)
        throw std::invalid_argument("bucket size must be positive, got " +
                                    std::to_string(bucket_size));
    if (test.rgb.size() != test.pixel_count() * 3 ||
        reference.rgb.size() != reference.pixel_count() * 3)
        throw std::invalid_argument("image rgb size does not match its resolution");
    ErrorMetrics m;
    if (test.pixel_count() == 0) return m;

    // One row-major pass: the whole-image sums then do not depend on the bucket size, so
    // `compare --bucket-size 8` and `--bucket-size 16` agree on E to the last bit.
    const uint32_t w = test.width, h = test.height, b = uint32_t(bucket_size);
    const uint32_t buckets_x = (w + b - 1) / b, buckets_y = (h + b - 1) / b;
    std::vector<double> bucket_abs(size_t(buckets_x) * buckets_y, 0.0);
    double abs_sum = 0, sq_sum = 0, rel_sum = 0;
    // The mean bias's sums, in the same pass: the reference's total, each block's sum of
    // the per-pixel differences, and the sum of their squares.
    const uint32_t s = bias_block_side(w, h), blocks_x = (w + s - 1) / s;
    std::vector<double> block_diff(size_t(blocks_x) * ((h + s - 1) / s), 0.0);
    double ref_sum = 0, diff_sq_sum = 0;
    for (uint32_t y = 0; y < h; ++y) {
        double* bucket_row = bucket_abs.data() + size_t(y / b) * buckets_x;
        double* block_row = block_diff.data() + size_t(y / s) * blocks_x;
        for (uint32_t x = 0; x < w; ++x) {
            const size_t i = (size_t(y) * w + x) * 3;
            double pixel_abs = 0, pixel_diff = 0;
            for (size_t c = 0; c < 3; ++c) {
                const double a = test.rgb[i + c], r = reference.rgb[i + c];
                const double d = a - r;
                pixel_abs += std::abs(d);
                pixel_diff += d;
                ref_sum += r;
                sq_sum += d * d;
                rel_sum += d * d / (r * r + 1e-2);
            }
            abs_sum += pixel_abs;
            bucket_row[x / b] += pixel_abs;
            block_row[x / s] += pixel_diff / 3.0;
            diff_sq_sum += (pixel_diff / 3.0) * (pixel_diff / 3.0);
        }
    }
    std::vector<double> bucket_errors;
    bool any_nan = false;
    for (uint32_t by = 0; by < buckets_y; ++by) {
        for (uint32_t bx = 0; bx < buckets_x; ++bx) {
            // Edge buckets are smaller; each is averaged over its own pixels (and RGB).
            const double pixels =
                double(std::min(b, w - bx * b)) * std::min(b, h - by * b);
            const double e = bucket_abs[size_t(by) * buckets_x + bx] / (3.0 * pixels);
            any_nan = any_nan || std::isnan(e);
            bucket_errors.push_back(e);
        }
    }
    const double samples = 3.0 * double(test.pixel_count());
    m.mean_abs = abs_sum / samples;
    m.rmse = std::sqrt(sq_sum / samples);
    m.relative_mse = rel_sum / samples;
    set_mean_bias(m, block_diff, w, h, s, ref_sum, diff_sq_sum);
    if (any_nan) {
        // A NaN would break the sort's ordering; report it rather than a misleading
        // number.
        m.max_bucket = m.p99_bucket = std::nan("");
    } else {
        m.max_bucket = *std::max_element(bucket_errors.begin(), bucket_errors.end());
        m.p99_bucket = nearest_rank(std::move(bucket_errors), 99.0);
    }
    return m;
}

}  // namespace aliquot
