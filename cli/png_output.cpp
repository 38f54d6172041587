#include "png_output.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <system_error>

#include "commands.h"
#include "http_api.h"
#include "render_options.h"

namespace aliquot::cli {

namespace {

// The dashboard's exposure slider reaches +-6; 2^20 is far past any image's range.
constexpr double kMaxExposure = 20;

}  // namespace

void PngOptions::add_to(CLI::App& cmd) {
    CLI::Option* flag =
        cmd.add_flag("--png", png,
                     "also write an 8-bit sRGB PNG beside the EXR (same name, .png), to "
                     "look at in any image viewer");
    cmd.add_option("--exposure", exposure,
                   "with --png: brighten (or darken, negative) the PNG by this many "
                   "stops, -20..20")
        ->capture_default_str()
        ->needs(flag);
}

std::string PngOptions::path_beside(const std::string& exr_path) const {
    if (!png) return "";
    if (!(std::abs(exposure) <= kMaxExposure))
        throw UsageError("--exposure: must be -20..20 stops");
    const std::string path = std::filesystem::path(exr_path).replace_extension(".png");
    if (path == exr_path)
        throw UsageError("--png: --out " + exr_path +
                         " would be overwritten by the PNG; name the EXR .exr");
    check_writable(path, "--png");
    return path;
}

void write_png(const Image& image, double exposure, const std::filesystem::path& path) {
    // The HTTP API's preview, not shrunk: one tone mapping for the dashboard and the CLI.
    const std::string bytes =
        http_api::preview_png(image, exposure, std::max(image.width, image.height));
    const std::filesystem::path part = path.string() + ".part";
    {
        std::ofstream out(part, std::ios::binary | std::ios::trunc);
        out.write(bytes.data(), std::streamsize(bytes.size()));
        out.close();
        if (!out) {
            std::error_code ignored;
            std::filesystem::remove(part, ignored);
            throw CommandError("--png: cannot write " + path.string());
        }
    }
    std::filesystem::rename(part, path);
}

}  // namespace aliquot::cli
