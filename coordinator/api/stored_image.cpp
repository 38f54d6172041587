#include "stored_image.h"

#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "exr_io.h"
#include "exr_rgb_copy.h"

namespace aliquot {

std::filesystem::path stored_image(const std::filesystem::path& full, bool aovs) {
    if (aovs) return full;
    const std::filesystem::path rgb = full.parent_path() / "image-rgb.exr";
    std::error_code ec;
    if (std::filesystem::exists(rgb, ec)) return rgb;
    // mkstemp: a name nobody can guess, made 0600. Two fetches at once each make one;
    // the rename of either leaves a whole file.
    std::string temporary = (full.parent_path() / "image-rgb.exr.XXXXXX").string();
    const int fd = ::mkstemp(temporary.data());
    if (fd < 0)
        throw ImageFileError("cannot write beside " + full.string() + ": " +
                             std::strerror(errno));
    ::close(fd);
    try {
        copy_exr_rgb(full, temporary);
    } catch (...) {
        std::filesystem::remove(temporary, ec);
        throw;
    }
    std::filesystem::rename(temporary, rgb, ec);
    if (ec) {
        std::filesystem::remove(temporary, ec);
        throw ImageFileError("cannot write " + rgb.string() + ": " + ec.message());
    }
    return rgb;
}

}  // namespace aliquot
