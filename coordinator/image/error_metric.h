// Error metrics between a test image and a reference, shared by coordinator and CLI.
#pragma once

#include <stdexcept>

#include "image.h"

namespace aliquot {

struct ErrorMetrics {
    double mean_abs = 0;      // the seed's E: mean |A-B| per pixel, averaged over RGB
    double rmse = 0;          // sqrt(mean (A-B)^2) over pixels and channels
    double relative_mse = 0;  // mean (A-B)^2 / (B^2 + 1e-2), B the reference
    double max_bucket = 0;    // largest per-bucket mean_abs
    double p99_bucket = 0;    // 99th percentile of per-bucket mean_abs
};

class ImageMismatch : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

// `bucket_size`: side of the square buckets for the per-bucket statistics (edge buckets
// are smaller). Throws ImageMismatch when the resolutions differ.
ErrorMetrics compare_images(const Image& test, const Image& reference,
                            int bucket_size = 16);

}  // namespace aliquot
