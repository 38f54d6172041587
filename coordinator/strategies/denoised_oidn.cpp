// `denoised`'s denoiser in a render: Open Image Denoise, through the denoise room.
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include "denoised_strategy.h"
#include "denoiser.h"

namespace aliquot {

DenoiseFunction oidn_denoise_function(std::shared_ptr<const std::atomic<bool>> stop) {
    // One library and device for the process, opened by the first render that asks (a
    // dlopen and OIDN's device take tens of milliseconds); a failure is tried again by
    // the next, so a library installed meanwhile is found.
    static std::mutex mutex;
    static std::shared_ptr<const Denoiser> opened;
    std::shared_ptr<const Denoiser> denoiser;
    {
        std::lock_guard lock(mutex);
        if (!opened) {
            std::string error;
            opened = Denoiser::open(&error);
            if (!opened)
                throw std::invalid_argument(
                    "method 'denoised' needs Open Image Denoise: " + error);
        }
        denoiser = opened;
    }
    return
        [denoiser, stop](const Image& colour, const Image* albedo, const Image* normal) {
            std::string error;
            std::optional<Image> out =
                denoiser->denoise(colour, albedo, normal, &error, stop.get());
            if (!out) throw std::runtime_error("denoising a half image failed: " + error);
            return std::move(*out);
        };
}

}  // namespace aliquot
