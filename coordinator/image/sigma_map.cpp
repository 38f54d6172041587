#include "sigma_map.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace aliquot {

namespace {

const std::vector<float>* channel(const Image& image, const std::string& name) {
    for (const Image::Channel& c : image.extra)
        if (c.name == name && c.values.size() == image.pixel_count()) return &c.values;
    return nullptr;
}

}  // namespace

std::vector<float> per_sample_sigma(const Image& image) {
    const std::vector<float>* variance = channel(image, "variance");
    const std::vector<float>* spp = channel(image, "spp");
    if (!variance || !spp)
        throw std::invalid_argument(
            "the image has no 'variance' and 'spp' channels (render it with --aovs)");
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
