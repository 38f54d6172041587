#include "resolution.h"

#include <charconv>
#include <stdexcept>
#include <string>

namespace aliquot {

namespace {

// One side: digits only (no sign, space or '+', which sscanf and strtoul let through).
// Values too large for uint64_t read as out of range, never as a wrapped-around number.
bool read_side(std::string_view text, uint32_t& side) {
    if (text.empty() || text.front() < '0' || text.front() > '9') return false;
    uint64_t value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (end != text.data() + text.size()) return false;
    if (ec == std::errc::result_out_of_range)
        value = UINT64_MAX;
    else if (ec != std::errc())
        return false;
    if (value < 1 || value > kMaxResolutionSide) return false;
    side = uint32_t(value);
    return true;
}

}  // namespace

Resolution parse_resolution(std::string_view text) {
    Resolution r;
    const size_t x = text.find('x');
    if (x == std::string_view::npos || !read_side(text.substr(0, x), r.width) ||
        !read_side(text.substr(x + 1), r.height))
        throw std::invalid_argument("expected WxH with each side in 1.." +
                                    std::to_string(kMaxResolutionSide) +
                                    ", e.g. 256x256, got \"" + std::string(text) + "\"");
    return r;
}

}  // namespace aliquot
