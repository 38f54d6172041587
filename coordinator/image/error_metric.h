// Error metrics between a test image and a reference, shared by coordinator and CLI.
#pragma once

#include <stdexcept>
#include <string>

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
    // bias) or when either image holds a NaN or an infinity.
    double mean_bias = 0;
    // Its standard error, from batch means: the image is cut into blocks of 16x16 pixels
    // (smaller for an image of fewer than 16 such blocks, never the metric's bucket
    // size), and the spread of the blocks' mean differences (A - B averaged over RGB),
    // each weighted by its pixels, gives the error of the image's mean, over B's mean.
    // Pixels are not taken as independent: a denoiser spreads each pixel's error over its
    // neighbours and a caustic's fireflies cluster, and both stay inside a block. Blocks
    // are taken as independent (a kernel wider than a block still makes it run low), and
    // from K blocks it has K - 1 degrees of freedom: with few blocks it is itself noisy,
    // so where the per-pixel error (pixels taken as independent) is larger, that is it.
    // The reference's own noise is in it too. NaN with mean_bias, and for a single block.
    double mean_bias_se = 0;
};

// Whether |mean_bias| exceeds 3 standard errors: a bias the image's noise does not
// explain. False when either is NaN.
bool bias_beyond_noise(const ErrorMetrics& m);

// The mean bias as one line says it: "-1.68 % ± 0.05 %, beyond 3 SE: biased",
// "+0.1 % ± 0.2 %, within 3 SE", or "–" and why there is none (a black reference, an
// image or reference holding NaN or inf, too few blocks for a standard error).
std::string mean_bias_text(const ErrorMetrics& m);

class ImageMismatch : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

// `bucket_size`: side of the square buckets for the per-bucket statistics (edge buckets
// are smaller). Throws ImageMismatch when the resolutions differ.
ErrorMetrics compare_images(const Image& test, const Image& reference,
                            int bucket_size = 16);

}  // namespace aliquot
