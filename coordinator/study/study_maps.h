// The per-pixel maps a study's maps chart shows, as NumPy .npy files the report reads.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "image.h"

namespace aliquot {

// Per pixel: R, G, B of the render, its samples, and |render - reference| averaged over
// RGB, as a float32 array of shape (height, width, 5). Throws StudyError.
void write_study_maps(const std::filesystem::path& path, const Image& image,
                      const Image& reference);

}  // namespace aliquot
