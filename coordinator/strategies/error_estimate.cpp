#include "error_estimate.h"

#include <cmath>
#include <memory>

#include "bands.h"

namespace aliquot {

double estimate_mean_abs_error(const Accumulator& merged) {
    // The pixels' terms are computed in bands on the pool's threads; their sum is taken
    // in pixel order on this one, so the estimate is the same to the last bit whatever
    // the threads (and as it was when one thread did both).
    const size_t pixels = merged.pixel_count();
    const std::unique_ptr<double[]> term(new double[pixels]);
    for_each_band(pixels, kBandPixels, [&](size_t, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            if (merged.samples(i) < 2) {
                term[i] = -1.0;  // not estimated: fewer than two samples
                continue;
            }
            double even[3], odd[3];
            merged.half_means(i, even, odd);
            term[i] = (std::abs(even[0] - odd[0]) + std::abs(even[1] - odd[1]) +
                       std::abs(even[2] - odd[2])) /
                      3.0;
        }
    });
    double sum = 0;
    size_t n = 0;
    for (size_t i = 0; i < pixels; ++i) {
        if (term[i] < 0) continue;
        sum += term[i];
        ++n;
    }
    return n ? 0.5 * sum / double(n) : -1.0;
}

}  // namespace aliquot
