// --png and --exposure: an 8-bit sRGB PNG written beside an EXR (out/x.exr ->
// out/x.png), for a user who has no EXR viewer. The same picture as the dashboard's
// preview, at full size.
#pragma once

#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>

#include "image.h"

namespace aliquot::cli {

struct PngOptions {
    bool png = false;
    double exposure = 0;  // stops: the image is scaled by 2^exposure before sRGB

    void add_to(CLI::App& cmd);
    // Where --png writes for the EXR at `exr_path`, its extension replaced by .png (""
    // with no --png), checked before any work: UsageError for an exposure outside -20..20
    // or an EXR named .png, CommandError when the PNG cannot be written.
    std::string path_beside(const std::string& exr_path) const;
};

// Writes `image` as a PNG at `path` (whole, then renamed into place); CommandError naming
// the path when it cannot be written.
void write_png(const Image& image, double exposure, const std::filesystem::path& path);

}  // namespace aliquot::cli
