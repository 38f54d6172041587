// x / k for many x and one k, without a 64-bit division each (tens of cycles, most of a
// pass over a 1920x1080 image's counts): the quotient from floating point, then
// corrected to the exact one, so it is x / k whatever the rounding (for x below 2^53,
// where the guess is off by at most a few and q * k cannot overflow).
#pragma once

#include <cstdint>

namespace aliquot {

class ExactQuotient {
public:
    explicit ExactQuotient(uint64_t k) : k_(k), inverse_(1.0 / double(k)) {}
    uint64_t operator()(uint64_t x) const {
        uint64_t q = uint64_t(double(x) * inverse_);
        while (q * k_ > x) --q;
        while ((q + 1) * k_ <= x) ++q;
        return q;
    }

private:
    uint64_t k_;
    double inverse_;
};

}  // namespace aliquot
