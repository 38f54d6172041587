// The extra channels of a render's EXR (`--aovs`), named "layer.channel" as OpenEXR's
// multi-part conventions have it: OIIO (`oiiotool --info -v`), tev and Blender's
// compositor each show them as a layer of its own, "sampleCount" and "variance", whose
// one channel is Y (a grey value), beside the unprefixed R, G, B of the beauty image.
#pragma once

#include <string>

namespace aliquot {

// Samples merged into each pixel.
inline constexpr const char* kSampleCountChannel = "sampleCount.Y";
// The variance of each pixel's mean luminance: the sample variance over the sample count.
inline constexpr const char* kVarianceChannel = "variance.Y";

// The first hit's mean albedo and world-space normal (components in [-1, 1]), of renders
// that will be denoised (issue 34): the layers OIDN's "albedo" and "normal" images are
// made of, in RGB / XYZ order.
inline constexpr const char* kAlbedoChannels[3] = {"albedo.R", "albedo.G", "albedo.B"};
inline constexpr const char* kNormalChannels[3] = {"normal.X", "normal.Y", "normal.Z"};

// The colour denoised by Open Image Denoise (`aliquot render --denoise`), beside the raw
// R, G, B: `aliquot compare` measures it too.
inline constexpr const char* kDenoisedChannels[3] = {"denoised.R", "denoised.G",
                                                     "denoised.B"};

// The name a channel read from a file goes by now: EXRs written before the layers had
// "spp" and "variance" (a data directory's finished renders keep theirs).
inline std::string current_channel_name(const std::string& name) {
    if (name == "spp") return kSampleCountChannel;
    if (name == "variance") return kVarianceChannel;
    return name;
}

}  // namespace aliquot
