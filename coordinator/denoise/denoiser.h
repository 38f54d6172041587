// Denoiser: Intel Open Image Denoise's "RT" filter on a render's HDR colour, with its
// first-hit albedo and normal when the render has them. OIDN is loaded at run time
// (dlopen), so nothing links it at build time and a farm without it runs; docs/DENOISE.md
// says where it comes from.
#pragma once

#include <atomic>
#include <memory>
#include <optional>
#include <string>

#include "image.h"

namespace aliquot {

// Where open() looks for libOpenImageDenoise.so.2, the first that loads wins:
//   1. the file ALIQUOT_OIDN_LIBRARY names, and nothing else when it is set (so a test
//      or a user can say which library, or that there is none);
//   2. pyoidn's copy in the repository's .venv (scripts/install-deps.sh installs it):
//      the source tree's, baked in at configure time;
//   3. the loader's own search (LD_LIBRARY_PATH, a system install).
// A path in 1 or 2 under a folder another user owns or may write is refused unopened.
inline constexpr const char* kOidnLibraryVariable = "ALIQUOT_OIDN_LIBRARY";

class Denoiser {
public:
    // A denoiser on OIDN's CPU device, or nullptr with *error saying what was tried and
    // the command that installs the library (scripts/install-deps.sh) when it was not
    // found.
    static std::unique_ptr<Denoiser> open(std::string* error);
    ~Denoiser();
    Denoiser(const Denoiser&) = delete;
    Denoiser& operator=(const Denoiser&) = delete;

    // The colour's rgb denoised as HDR (linear, [0, +inf)): an image of its size with rgb
    // only (no extra channels, its attributes kept). albedo and normal are optional
    // auxiliary images of the same size, their rgb the mean first-hit albedo ([0, 1]) and
    // normal ([-1, 1]): albedo alone, both, or neither (OIDN has no model for a normal
    // alone); nullptr when the render has none. nullopt and *error on a size mismatch, a
    // normal without an albedo, or an OIDN error. The same inputs give the same bytes on
    // one machine (docs/DENOISE.md, "Determinism"). Thread-safe: calls on one Denoiser
    // run one at a time (OIDN serialises a device's work anyway). With `stop`, OIDN gives
    // up soon after it turns true (between the network's steps), and the call fails:
    // minutes of work at 8192x8192 are not waited out for a render that has ended.
    std::optional<Image> denoise(const Image& colour, const Image* albedo,
                                 const Image* normal, std::string* error,
                                 const std::atomic<bool>* stop = nullptr) const;

    // The file the library was loaded from, for logs and the EXR's attributes.
    const std::string& library_path() const;

private:
    struct Loaded;
    explicit Denoiser(std::unique_ptr<Loaded> loaded);
    std::unique_ptr<Loaded> loaded_;
};

}  // namespace aliquot
