#include "error_estimate.h"

#include <cmath>

namespace aliquot {

double estimate_mean_abs_error(const Accumulator& merged) {
    double sum = 0;
    size_t n = 0;
    for (size_t i = 0; i < merged.pixel_count(); ++i) {
        if (merged.samples(i) < 2) continue;
        double even[3], odd[3];
        merged.half_means(i, even, odd);
        sum += (std::abs(even[0] - odd[0]) + std::abs(even[1] - odd[1]) +
                std::abs(even[2] - odd[2])) /
               3.0;
        ++n;
    }
    return n ? 0.5 * sum / double(n) : -1.0;
}

}  // namespace aliquot
