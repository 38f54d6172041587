#include "denoised_render.h"

#include <algorithm>

#include "aov_channels.h"
#include "aov_layer.h"

namespace aliquot {

std::optional<Image> denoise_render(const Denoiser& denoiser, const Image& render,
                                    std::string* error, bool* used_aux) {
    const std::optional<Image> albedo = layer_image(render, kAlbedoChannels);
    // A normal without its albedo is not an input OIDN has a model for: then neither.
    const std::optional<Image> normal =
        albedo ? layer_image(render, kNormalChannels) : std::nullopt;
    if (used_aux) *used_aux = albedo.has_value();
    Image colour(render.width, render.height);
    colour.rgb = render.rgb;
    colour.attributes = render.attributes;
    return denoiser.denoise(colour, albedo ? &*albedo : nullptr,
                            normal ? &*normal : nullptr, error);
}

void add_denoised_layer(const Image& denoised, bool used_aux, Image& render) {
    std::erase_if(render.extra, [](const Image::Channel& ch) {
        return std::find(std::begin(kDenoisedChannels), std::end(kDenoisedChannels),
                         ch.name) != std::end(kDenoisedChannels);
    });
    for (int c = 0; c < 3; ++c) {
        Image::Channel ch{kDenoisedChannels[c],
                          std::vector<float>(denoised.pixel_count())};
        for (size_t i = 0; i < denoised.pixel_count(); ++i)
            ch.values[i] = denoised.rgb[3 * i + c];
        render.extra.push_back(std::move(ch));
    }
    render.attributes["aliquot:denoised"] =
        std::string("Open Image Denoise RT, HDR, high quality, CPU device, ") +
        (used_aux ? "with first-hit albedo and normal" : "colour only");
}

std::optional<Image> denoised_layer(const Image& render) {
    return layer_image(render, kDenoisedChannels);
}

}  // namespace aliquot
