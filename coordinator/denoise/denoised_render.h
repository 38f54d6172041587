// A render's denoised layer ("denoised.R/G/B", aov_channels.h): its colour denoised with
// its own first-hit albedo and normal layers when it has them, added to the image that an
// EXR is written from, and found again in one read back.
#pragma once

#include <optional>
#include <string>

#include "denoiser.h"
#include "image.h"

namespace aliquot {

// The render's colour denoised, with its albedo.R/G/B and normal.X/Y/Z layers as OIDN's
// aux images when it has them (both, or the albedo alone); nullopt and *error on failure.
// *used_aux (optional) says whether they were there.
std::optional<Image> denoise_render(const Denoiser& denoiser, const Image& render,
                                    std::string* error, bool* used_aux = nullptr);

// Adds `denoised`'s rgb to `render` as the layer denoised.R/G/B, replacing one there, and
// the attribute "aliquot:denoised" saying how it was made.
void add_denoised_layer(const Image& denoised, bool used_aux, Image& render);

// The layer denoised.R/G/B of an image (an EXR read back) as an Image of its own, or
// nullopt when it has none.
std::optional<Image> denoised_layer(const Image& render);

}  // namespace aliquot
