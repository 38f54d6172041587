#include "aov_layer.h"

#include <string>

namespace aliquot {

std::optional<Image> layer_image(const Image& image, const char* const (&names)[3]) {
    const Image::Channel* found[3] = {nullptr, nullptr, nullptr};
    for (const Image::Channel& ch : image.extra)
        for (int c = 0; c < 3; ++c)
            if (ch.name == names[c] && ch.values.size() == image.pixel_count())
                found[c] = &ch;
    if (!found[0] || !found[1] || !found[2]) return std::nullopt;
    Image out(image.width, image.height);
    for (size_t i = 0; i < image.pixel_count(); ++i)
        for (int c = 0; c < 3; ++c) out.rgb[3 * i + c] = found[c]->values[i];
    return out;
}

}  // namespace aliquot
