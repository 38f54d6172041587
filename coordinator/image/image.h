// Image: a linear float RGB image with optional extra per-pixel channels (AOVs).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace aliquot {

struct Image {
    uint32_t width = 0, height = 0;
    std::vector<float> rgb;  // 3 floats per pixel, row 0 at the top

    struct Channel {
        std::string name;
        std::vector<float> values;  // one float per pixel
    };
    std::vector<Channel> extra;  // e.g. "sampleCount.Y", "variance.Y" (aov_channels.h)
    // Written as EXR string attributes, e.g. "aliquot:seed" -> "7": what made the image.
    // Names carry a "namespace:" prefix, which keeps them apart from OpenEXR's own.
    std::map<std::string, std::string> attributes;

    Image() = default;
    Image(uint32_t w, uint32_t h) : width(w), height(h), rgb(size_t(w) * h * 3, 0.0f) {}
    size_t pixel_count() const { return size_t(width) * height; }
};

}  // namespace aliquot
