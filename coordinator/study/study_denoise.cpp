#include "study_denoise.h"

#include "denoised_render.h"
#include "study_definition.h"

namespace aliquot {

// The denoise room's denoise_render, which finds the first-hit layers and hands them to
// OIDN; the study only insists they were there, so that no figure of its comes from a
// colour-only denoise.
Image denoise_render(const Denoiser& denoiser, const Image& render,
                     const std::string& key) {
    std::string error;
    bool used_aux = false;
    std::optional<Image> out = denoise_render(denoiser, render, &error, &used_aux);
    if (!out) throw StudyError("denoising render " + key + ": " + error);
    if (!used_aux)
        throw StudyError(
            "render " + key +
            " has no albedo and normal layers to denoise with; it was traced "
            "without its first hits");
    return std::move(*out);
}

}  // namespace aliquot
