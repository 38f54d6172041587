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
    // The image's mean bias: (mean of A - mean of B) / mean of B over pixels and RGB, a
    // fraction (-0.02: A is 2 % too dark). E rewards a method that darkens heavy-tailed
    // pixels towards their median (docs/RESULTS.md, "Is `optimal` biased low?"); this
    // shows it. NaN when B's mean is not positive (a black reference has no relative
    // bias).
    double mean_bias = 0;
    // Its standard error: the standard deviation of the per-pixel differences (A - B
    // averaged over RGB) over sqrt(pixels), over B's mean. It treats pixels as
    // independent (a pixel's channels share their paths, so a pixel, not a channel, is
    // the unit); the reference's own noise is in it too. NaN with mean_bias.
    double mean_bias_se = 0;
};

// Whether |mean_bias| exceeds 3 standard errors: a bias the image's noise does not
// explain. False when either is NaN.
bool bias_beyond_noise(const ErrorMetrics& m);

class ImageMismatch : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

// `bucket_size`: side of the square buckets for the per-bucket statistics (edge buckets
// are smaller). Throws ImageMismatch when the resolutions differ.
ErrorMetrics compare_images(const Image& test, const Image& reference,
                            int bucket_size = 16);

}  // namespace aliquot
