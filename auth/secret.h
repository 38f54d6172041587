// Unguessable values and comparing them without telling an attacker how close they came.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace aliquot {

// `size` bytes from the kernel's CSPRNG (getrandom(2)); throws std::runtime_error if it
// fails.
void random_bytes(void* out, size_t size);

// `bytes` random bytes as 2 * bytes lowercase hex digits.
std::string random_hex(size_t bytes);

// Whether a == b, taking the same time for every a of a given length: a caller that
// guesses a token learns nothing from how long a wrong guess took to refuse.
bool constant_time_equal(std::string_view a, std::string_view b);

}  // namespace aliquot
