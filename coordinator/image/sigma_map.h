// The per-sample noise of a render written with its AOVs (aliquot render --aovs): what
// the oracle allocates by when the render is a separate high-spp one.
#pragma once

#include <vector>

#include "image.h"

namespace aliquot {

// Per pixel, the standard deviation of one sample's luminance: sqrt(variance * spp), the
// `variance` channel being that of the pixel's mean. Throws std::invalid_argument when
// the image lacks the channels or holds a negative or non-finite value.
std::vector<float> per_sample_sigma(const Image& image);

}  // namespace aliquot
