// The cube root optimal's weights take, w = r^(2/3) = cbrt(r^2) for every pixel of every
// plan: std::cbrt was a third of a round end's plan at 1920x1080 (~20 ns a pixel), these
// ~6 ns. A first guess of x^(-1/3) from the high bits of x (the exponent divided by -3;
// the constant is the one with the smallest worst error, 3.4 %), four of Newton's steps
// y <- y (4 - x y^3) / 3, which need no division and square the error each time, and
// x y^2 = x^(1/3), within 2e-15 of it (cube_root_test.cpp). The guess (integer
// arithmetic) and the steps (doubles) are separate so that a caller can run each in a
// loop of its own: in one loop the compiler vectorises neither. Their bits are not
// std::cbrt's; they are the same on every machine that rounds doubles as IEEE 754 says.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace aliquot {

// Whether the steps below hold for x: a normal, finite x > 0 (without a branch).
inline bool cube_root_steps_hold(double x) {
    return (x >= std::numeric_limits<double>::min()) &
           (x <= std::numeric_limits<double>::max());
}

// About x^(-1/3), for a normal, finite x > 0.
inline double inverse_cube_root_guess(double x) {
    uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    bits = uint64_t(0x553EF100u - uint32_t(bits >> 32) / 3) << 32;
    double y;
    std::memcpy(&y, &bits, sizeof y);
    return y;
}

// x^(1/3) from the guess y above.
inline double cube_root_from_guess(double x, double y) {
    for (int step = 0; step < 4; ++step)
        y = y * (4.0 / 3.0 - x * y * y * y * (1.0 / 3.0));
    return x * y * y;
}

// x^(1/3) for any x: the two above where they hold, std::cbrt elsewhere (0, subnormals,
// infinity, NaN, x < 0).
inline double cube_root(double x) {
    return cube_root_steps_hold(x) ? cube_root_from_guess(x, inverse_cube_root_guess(x))
                                   : std::cbrt(x);
}

}  // namespace aliquot
