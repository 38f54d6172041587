#include "exact_quotient.h"

#include <gtest/gtest.h>

namespace aliquot {
namespace {

TEST(ExactQuotient, IsTheIntegerQuotientWhereTheFloatingPointGuessIsOff) {
    // Divisors whose inverse is not exact in binary, numerators on either side of their
    // multiples and near 2^53, where the guess from floating point is off by one.
    for (const uint64_t k : {1ull, 3ull, 7ull, 10ull, 16ull, 49ull, 1000003ull}) {
        const ExactQuotient quotient(k);
        for (const uint64_t base : {0ull, 1ull << 20, 1ull << 32, (1ull << 53) - 1000})
            for (uint64_t x = base; x < base + 3 * k + 2; ++x)
                ASSERT_EQ(quotient(x), x / k) << x << " / " << k;
    }
}

}  // namespace
}  // namespace aliquot
