// OpenEXR reading and writing. Output is deterministic: the same Image gives the same
// bytes.
#pragma once

#include <filesystem>
#include <stdexcept>

#include "image.h"

namespace aliquot {

class ImageFileError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Writes float R, G, B plus every extra channel (FLOAT, ZIP compression). Throws
// ImageFileError naming the path when the file cannot be written.
void write_exr(const std::filesystem::path& path, const Image& image);

// Reads R, G, B (any pixel type, converted to float) and every other channel as extra.
Image read_exr(const std::filesystem::path& path);

}  // namespace aliquot
