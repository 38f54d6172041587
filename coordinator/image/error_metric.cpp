// Error metrics between a test image and a reference (the seed's E, RMSE, relMSE,
// buckets, the image's mean bias).
#include "error_metric.h"

#include <algorithm>
#include <cmath>
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

// mean_bias and its standard error from the pass's sums over `pixels` pixels.
void set_mean_bias(ErrorMetrics& m, double pixels, double ref_mean, double diff_sum,
                   double diff_sq_sum) {
    if (!(ref_mean > 0)) {
        m.mean_bias = m.mean_bias_se = std::nan("");
        return;
    }
    const double diff_mean = diff_sum / pixels;
    // Sample variance of the per-pixel differences; rounding can take it a hair below 0.
    const double variance =
        pixels > 1 ? std::max(0.0, (diff_sq_sum - diff_sum * diff_mean) / (pixels - 1))
                   : 0.0;
    m.mean_bias = diff_mean / ref_mean;
    m.mean_bias_se = std::sqrt(variance / pixels) / ref_mean;
}

}  // namespace

bool bias_beyond_noise(const ErrorMetrics& m) {
    return std::abs(m.mean_bias) > 3.0 * m.mean_bias_se;
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
    // The mean bias's sums, in the same pass: the reference's total, and the per-pixel
    // differences' sum and sum of squares.
    double ref_sum = 0, diff_sum = 0, diff_sq_sum = 0;
    for (uint32_t y = 0; y < h; ++y) {
        double* bucket_row = bucket_abs.data() + size_t(y / b) * buckets_x;
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
            diff_sum += pixel_diff / 3.0;
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
    set_mean_bias(m, double(test.pixel_count()), ref_sum / samples, diff_sum,
                  diff_sq_sum);
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
