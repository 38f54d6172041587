// The one reader of "WxH" image sizes, with the one limit on a side, for every door a
// resolution comes in by (CLI options, study files, the HTTP API).
#pragma once

#include <cstdint>
#include <string_view>

namespace aliquot {

// Larger images are refused before any buffer is sized from them. Operators may set a
// lower limit of their own (the farm's --max-resolution).
constexpr uint32_t kMaxResolutionSide = 8192;

struct Resolution {
    uint32_t width = 0, height = 0;
};

// Digits, 'x', digits; each side in 1..kMaxResolutionSide. Throws std::invalid_argument
// with a message the caller prefixes with the field's name, e.g.
// `expected WxH with each side in 1..8192, e.g. 256x256, got "0x3"`.
Resolution parse_resolution(std::string_view text);

}  // namespace aliquot
