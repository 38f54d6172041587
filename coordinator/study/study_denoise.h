// A study's renders measured after denoising (a study with "denoise", issue 34): the
// render's colour through Open Image Denoise with its first-hit albedo and normal, then
// the same metrics against the same reference as the raw image.
#pragma once

#include <string>

#include "denoiser.h"
#include "error_metric.h"
#include "image.h"

namespace aliquot {

// The colour of `render` (with its "albedo.*" and "normal.*" layers) denoised, with
// only R, G, B. Throws StudyError, naming `key`, when the layers are missing (the
// render was traced without its first hits) or OIDN fails.
Image denoise_render(const Denoiser& denoiser, const Image& render,
                     const std::string& key);

}  // namespace aliquot
