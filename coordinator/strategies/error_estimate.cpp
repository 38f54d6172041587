#include "error_estimate.h"

namespace aliquot {

double estimate_mean_abs_error(const Accumulator& merged) {
    // The pixels' terms are kept by the accumulator as results merge
    // (Accumulator::half_difference); their sum is taken here in pixel order, so the
    // estimate is the same to the last bit as when each round's end computed every term.
    const size_t pixels = merged.pixel_count();
    double sum = 0;
    size_t n = 0;
    for (size_t i = 0; i < pixels; ++i) {
        const double term = merged.half_difference(i);
        if (term < 0) continue;  // not estimated: fewer than two samples
        sum += term;
        ++n;
    }
    return n ? 0.5 * sum / double(n) : -1.0;
}

}  // namespace aliquot
