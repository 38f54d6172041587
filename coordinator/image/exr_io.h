// OpenEXR reading and writing. Output is deterministic: the same Image gives the same
// bytes.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

#include "image.h"

namespace aliquot {

class ImageFileError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// decode_exr's refusal of bytes whose pixels would take more than its max_bytes: a
// matter of memory, not of a broken file.
class ImageTooLarge : public ImageFileError {
public:
    using ImageFileError::ImageFileError;
};

// The threads that compress an EXR's blocks of rows as it is written: one per hardware
// thread, in OpenEXR's own pool (made on first use), while the calling thread writes.
// The bytes do not depend on the count: each scan line is compressed alone and the
// lines are written in row order. A count of 0 compresses in the calling thread.
int exr_write_threads();

// Writes float R, G, B plus every extra channel (FLOAT, RLE compression: exr_format.h).
// Throws ImageFileError naming the path when the file cannot be written.
void write_exr(const std::filesystem::path& path, const Image& image,
               int threads = exr_write_threads());

// Reads R, G, B (any pixel type, converted to float) and every other channel as extra.
Image read_exr(const std::filesystem::path& path);

// The same bytes as write_exr and the same reading as read_exr, in memory: EXRs that
// cross the network never touch a file (a predictable temporary name is an attack).
// `name` says in errors where the bytes came from.
// With `expected`, bytes whose header claims another size are refused before any pixel
// is allocated (a few kilobytes could otherwise claim gigabytes); with `max_bytes`, so
// are bytes whose channels would take more than that decoded (4 bytes a pixel a channel).
// The header is read alone first: nothing it claims is allocated or decompressed unless
// it passes.
struct ExrSize {
    int64_t width = 0, height = 0;
};
std::string encode_exr(const Image& image, int threads = exr_write_threads());
Image decode_exr(const std::string& bytes, const std::string& name,
                 std::optional<ExrSize> expected = std::nullopt, uint64_t max_bytes = 0);

}  // namespace aliquot
