#include "study_maps.h"

#include <cmath>
#include <fstream>
#include <string>

#include "aov_channels.h"
#include "study_definition.h"

namespace aliquot {

namespace {

// NumPy's own format: a short header, then little-endian float32 data.
void write_npy(const std::filesystem::path& path, uint32_t height, uint32_t width,
               uint32_t channels, const std::vector<float>& data) {
    std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" +
                         std::to_string(height) + ", " + std::to_string(width) + ", " +
                         std::to_string(channels) + "), }";
    const size_t total = 10 + header.size() + 1;
    header.append((64 - total % 64) % 64, ' ');
    header += '\n';
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write("\x93NUMPY\x01\x00", 8);
    const uint16_t len = uint16_t(header.size());
    const char len_bytes[2] = {char(len & 0xff), char(len >> 8)};
    out.write(len_bytes, 2);
    out.write(header.data(), std::streamsize(header.size()));
    out.write(reinterpret_cast<const char*>(data.data()),
              std::streamsize(data.size() * 4));
    if (!out) throw StudyError("cannot write " + path.string());
}

}  // namespace

void write_study_maps(const std::filesystem::path& path, const Image& image,
                      const Image& reference) {
    const Image::Channel* spp = nullptr;
    for (const Image::Channel& c : image.extra)
        if (c.name == kSampleCountChannel) spp = &c;
    std::vector<float> data;
    data.reserve(image.pixel_count() * 5);
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        float err = 0;
        for (size_t c = 0; c < 3; ++c) {
            data.push_back(image.rgb[i * 3 + c]);
            err += std::abs(image.rgb[i * 3 + c] - reference.rgb[i * 3 + c]) / 3.0f;
        }
        data.push_back(spp ? spp->values[i] : 0.0f);
        data.push_back(err);
    }
    write_npy(path, image.height, image.width, 5, data);
}

}  // namespace aliquot
