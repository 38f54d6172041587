#include "sigma_map.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "aov_channels.h"

namespace aliquot {

namespace {

const std::vector<float>* channel(const Image& image, const std::string& name) {
    for (const Image::Channel& c : image.extra)
        if (current_channel_name(c.name) == name &&
            c.values.size() == image.pixel_count())
            return &c.values;
    return nullptr;
}

}  // namespace

std::vector<float> per_sample_sigma(const Image& image) {
    const std::vector<float>* variance = channel(image, kVarianceChannel);
    const std::vector<float>* spp = channel(image, kSampleCountChannel);
    if (!variance || !spp)
        throw std::invalid_argument(std::string("the image has no '") + kVarianceChannel +
                                    "' and '" + kSampleCountChannel +
                                    "' layers (render it with --aovs)");
    std::vector<float> sigma(image.pixel_count());
    for (size_t i = 0; i < sigma.size(); ++i) {
        const double v = double((*variance)[i]) * double((*spp)[i]);
        if (!(v >= 0) || std::isinf(v))
            throw std::invalid_argument("pixel " + std::to_string(i) +
                                        " has a negative or non-finite variance");
        sigma[i] = float(std::sqrt(v));
    }
    return sigma;
}

}  // namespace aliquot
