// Which stored EXR file FetchImage sends of a finished render, so that it is sent as it
// is read rather than decoded and encoded again in memory (docs/SECURITY.md, "gRPC
// limits").
#pragma once

#include <filesystem>

namespace aliquot {

// `full` (a render's image.exr, every layer) itself with `aovs`; without, its copy
// without the AOV layers beside it, made on first use (copy_exr_rgb, a band of rows at
// a time) under a temporary name and renamed into place, so that a reader never sees a
// partial file. Throws ImageFileError when the copy cannot be made.
std::filesystem::path stored_image(const std::filesystem::path& full, bool aovs);

}  // namespace aliquot
