#include "study_denoise.h"

#include "aov_channels.h"
#include "study_definition.h"

namespace aliquot {

namespace {

// The three channels `names` of `render` as the rgb of an image of its size; empty when
// any is missing.
Image layer(const Image& render, const char* const names[3]) {
    Image out(render.width, render.height);
    for (int c = 0; c < 3; ++c) {
        const Image::Channel* found = nullptr;
        for (const Image::Channel& ch : render.extra)
            if (ch.name == names[c]) found = &ch;
        if (!found || found->values.size() != render.pixel_count()) return {};
        for (size_t i = 0; i < render.pixel_count(); ++i)
            out.rgb[3 * i + c] = found->values[i];
    }
    return out;
}

}  // namespace

Image denoise_render(const Denoiser& denoiser, const Image& render,
                     const std::string& key) {
    const Image albedo = layer(render, kAlbedoChannels);
    const Image normal = layer(render, kNormalChannels);
    if (albedo.rgb.empty() || normal.rgb.empty())
        throw StudyError(
            "render " + key +
            " has no albedo and normal layers to denoise with; it was traced "
            "without its first hits");
    Image colour(render.width, render.height);
    colour.rgb = render.rgb;
    std::string error;
    std::optional<Image> out = denoiser.denoise(colour, &albedo, &normal, &error);
    if (!out) throw StudyError("denoising render " + key + ": " + error);
    return std::move(*out);
}

}  // namespace aliquot
