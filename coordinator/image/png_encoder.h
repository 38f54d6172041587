// PNG encoding of 8-bit images (grey, RGB or RGBA) with zlib, for the dashboard's
// previews: a tone-mapped preview is a few tens of kilobytes where the float image is
// megabytes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace aliquot {

// `pixels` holds width * height * channels bytes, row 0 at the top; channels is 1 (grey),
// 3 (RGB) or 4 (RGBA). Throws std::invalid_argument on a size mismatch.
std::string encode_png(const std::vector<uint8_t>& pixels, uint32_t width,
                       uint32_t height, int channels);

}  // namespace aliquot
