#include "png_encoder.h"

#include <zlib.h>

#include <cstdlib>
#include <stdexcept>

namespace aliquot {

namespace {

void put_u32(std::string& out, uint32_t v) {
    out.push_back(char(v >> 24));
    out.push_back(char(v >> 16));
    out.push_back(char(v >> 8));
    out.push_back(char(v));
}

void put_chunk(std::string& out, const char type[4], const std::string& data) {
    put_u32(out, uint32_t(data.size()));
    const size_t start = out.size();
    out.append(type, 4);
    out += data;
    const uint32_t crc = uint32_t(crc32(
        0, reinterpret_cast<const Bytef*>(out.data() + start), uInt(out.size() - start)));
    put_u32(out, crc);
}

uint8_t paeth(int a, int b, int c) {
    const int p = a + b - c;
    const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
    if (pa <= pb && pa <= pc) return uint8_t(a);
    return uint8_t(pb <= pc ? b : c);
}

// Filters one row with each of PNG's five filters and keeps the one whose output has the
// smallest sum of absolute (signed) bytes: the usual heuristic, and what makes a smooth
// preview or a piecewise-constant sample map compress several-fold.
void filter_row(const uint8_t* row, const uint8_t* prev, size_t n, int bpp,
                std::string& out) {
    std::string best, trial(n + 1, '\0');
    long best_cost = -1;
    for (int f = 0; f < 5; ++f) {
        trial[0] = char(f);
        long cost = 0;
        for (size_t i = 0; i < n; ++i) {
            const int a = i >= size_t(bpp) ? row[i - bpp] : 0;
            const int b = prev ? prev[i] : 0;
            const int c = (prev && i >= size_t(bpp)) ? prev[i - bpp] : 0;
            int pred = 0;
            switch (f) {
                case 1:
                    pred = a;
                    break;
                case 2:
                    pred = b;
                    break;
                case 3:
                    pred = (a + b) / 2;
                    break;
                case 4:
                    pred = paeth(a, b, c);
                    break;
                default:
                    break;
            }
            const uint8_t v = uint8_t(row[i] - pred);
            trial[i + 1] = char(v);
            cost += v < 128 ? v : 256 - v;
        }
        if (best_cost < 0 || cost < best_cost) {
            best_cost = cost;
            best = trial;
        }
    }
    out += best;
}

}  // namespace

std::string encode_png(const std::vector<uint8_t>& pixels, uint32_t width,
                       uint32_t height, int channels) {
    if (channels != 1 && channels != 3 && channels != 4)
        throw std::invalid_argument("png: channels must be 1, 3 or 4");
    const size_t stride = size_t(width) * size_t(channels);
    if (width == 0 || height == 0 || pixels.size() != stride * height)
        throw std::invalid_argument("png: pixel buffer does not match the image size");

    std::string raw;
    raw.reserve((stride + 1) * height);
    for (uint32_t y = 0; y < height; ++y)
        filter_row(pixels.data() + y * stride,
                   y ? pixels.data() + (y - 1) * stride : nullptr, stride, channels, raw);

    uLongf packed_size = compressBound(uLong(raw.size()));
    std::string packed(packed_size, '\0');
    if (compress2(reinterpret_cast<Bytef*>(packed.data()), &packed_size,
                  reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()),
                  6) != Z_OK)
        throw std::runtime_error("png: zlib compression failed");
    packed.resize(packed_size);

    std::string ihdr;
    put_u32(ihdr, width);
    put_u32(ihdr, height);
    ihdr.push_back(8);  // bit depth
    ihdr.push_back(char(channels == 1 ? 0 : channels == 3 ? 2 : 6));
    ihdr.append(3, '\0');  // deflate, adaptive filtering, no interlace

    std::string out("\x89PNG\r\n\x1a\n", 8);
    put_chunk(out, "IHDR", ihdr);
    put_chunk(out, "IDAT", packed);
    put_chunk(out, "IEND", {});
    return out;
}

}  // namespace aliquot
