// A three-channel layer of an image's extras (aov_channels.h: "albedo.R/G/B",
// "normal.X/Y/Z") as an RGB Image of its own: what a denoiser takes beside the colour,
// from a render or from an EXR read back.
#pragma once

#include <optional>

#include "image.h"

namespace aliquot {

// The channels `names` of `image` as the R, G, B of an image of its size, or nullopt
// when any of them is missing (a render that kept no first hits, an older file).
std::optional<Image> layer_image(const Image& image, const char* const (&names)[3]);

}  // namespace aliquot
