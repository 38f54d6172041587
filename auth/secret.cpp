#include "secret.h"

#include <sys/random.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace aliquot {

void random_bytes(void* out, size_t size) {
    auto* p = static_cast<unsigned char*>(out);
    while (size > 0) {
        const ssize_t got = getrandom(p, size, 0);
        if (got < 0) {
            if (errno == EINTR) continue;
            throw std::runtime_error(std::string("getrandom: ") + std::strerror(errno));
        }
        p += got;
        size -= size_t(got);
    }
}

std::string random_hex(size_t bytes) {
    std::string raw(bytes, '\0');
    random_bytes(raw.data(), raw.size());
    static const char digits[] = "0123456789abcdef";
    std::string hex;
    hex.reserve(2 * bytes);
    for (const char c : raw) {
        const auto b = static_cast<unsigned char>(c);
        hex.push_back(digits[b >> 4]);
        hex.push_back(digits[b & 15]);
    }
    return hex;
}

bool constant_time_equal(std::string_view a, std::string_view b) {
    // Every byte of `a` is looked at whatever `b` is; only the length can leak, and a
    // token's length is no secret (64 hex digits when the coordinator made it).
    unsigned char diff = a.size() == b.size() ? 0 : 1;
    for (size_t i = 0; i < a.size(); ++i) {
        const unsigned char other = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
        diff |= static_cast<unsigned char>(a[i]) ^ other;
    }
    // A volatile read keeps the compiler from ending the loop at the first difference.
    volatile unsigned char result = diff;
    return result == 0;
}

}  // namespace aliquot
