// The error a render can estimate about itself, without a reference: the even-index and
// odd-index half images are independent estimates of the same image.
#pragma once

#include "accumulator.h"

namespace aliquot {

// Estimated mean absolute error (the seed's E) of the full image. For unbiased noise,
// |even - odd| has twice the spread of |full - truth| (each half has twice the variance
// of the full mean, and their difference twice that again), so E_full ~ E(even, odd) / 2.
// Pixels with fewer than two samples are skipped. Returns -1 when no pixel qualifies.
double estimate_mean_abs_error(const Accumulator& merged);

}  // namespace aliquot
