#include "render_spec.h"

#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "log_line.h"
#include "sampler.h"

namespace aliquot {

std::string content_hash(const std::string& text) {
    // Two independent 64-bit chains of SplitMix64's mixer over 8-byte words: a 128-bit
    // content address. Not cryptographic; scenes and images come from the farm's own
    // users.
    uint64_t a = 0x243f6a8885a308d3ULL ^ text.size(),
             b = 0x13198a2e03707344ULL + text.size();
    size_t i = 0;
    for (; i + 8 <= text.size(); i += 8) {
        uint64_t w;
        std::memcpy(&w, text.data() + i, 8);
        a = mix64(a ^ w);
        b = mix64(b + w * 0x9e3779b97f4a7c15ULL);
    }
    uint64_t tail = 0;
    std::memcpy(&tail, text.data() + i, text.size() - i);
    a = mix64(a ^ tail ^ 0xa4093822299f31d0ULL);
    b = mix64(b + tail + 0x082efa98ec4e6c89ULL);
    char out[33];
    std::snprintf(out, sizeof out, "%016llx%016llx", (unsigned long long)a,
                  (unsigned long long)b);
    return out;
}

std::string render_name_error(const std::string& name) {
    if (name.size() > kMaxRenderName)
        return "at most " + std::to_string(kMaxRenderName) + " bytes, got " +
               std::to_string(name.size());
    if (!printable_utf8(name))
        return "must be UTF-8 text without control characters (tabs, newlines, escapes)";
    return "";
}

void validate(const RenderSpec& spec, uint32_t max_side) {
    if (const std::string why = render_name_error(spec.name); !why.empty())
        throw std::invalid_argument("name: " + why);
    if (spec.width == 0 || spec.height == 0 || spec.width > max_side ||
        spec.height > max_side)
        throw std::invalid_argument(
            "resolution: each side must be in 1.." + std::to_string(max_side) + ", got " +
            std::to_string(spec.width) + "x" + std::to_string(spec.height));
    validate(spec.strategy, spec.width, spec.height);
    if (spec.reference &&
        (spec.reference->width != spec.width || spec.reference->height != spec.height))
        throw std::invalid_argument(
            "reference: resolution differs: " + std::to_string(spec.reference->width) +
            "x" + std::to_string(spec.reference->height) + " vs " +
            std::to_string(spec.width) + "x" + std::to_string(spec.height));
}

}  // namespace aliquot
