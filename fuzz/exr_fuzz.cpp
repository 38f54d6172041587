// Fuzzes decode_exr as the coordinator's Submit runs it on a reference EXR from the
// network: the header read alone and checked against an expected size and a byte budget,
// then the pixels. Its contract: an Image within the budget, or an ImageFileError; never
// a crash, nor an allocation the budget does not allow.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "exr_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    // The seeds are 16x16; a budget of 4 planes of 256x256 lets a header claim more
    // pixels than the bytes hold without claiming more than the fuzzer's memory limit.
    constexpr uint64_t kBudget = 256 * 256 * 4 * sizeof(float);
    for (const bool expected : {false, true}) {
        try {
            const aliquot::Image image = aliquot::decode_exr(
                bytes, "fuzz",
                expected ? std::optional(aliquot::ExrSize{16, 16}) : std::nullopt,
                kBudget);
            if (image.rgb.size() != image.pixel_count() * 3) __builtin_trap();
        } catch (const aliquot::ImageFileError&) {
        }
    }
    return 0;
}
