// The format every EXR the farm writes has (write_exr, encode_exr, copy_exr_rgb): one
// place, since copy_exr_rgb promises write_exr's bytes.
#pragma once

#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfLineOrder.h>

namespace aliquot {

// RLE, not ZIP: at 1920x1080 ZIP took 0.47 CPU s to write a render's five float
// layers (0.41 at zlib level 1), RLE 0.09 (0.07 without compression), for files 22-27 %
// larger (17.4 MB against 22.1 at 64 spp): ZIP's zlib alone was about 1 % of a 64-spp
// render's worker CPU, issue 33's whole budget for the coordinator (docs/PERFORMANCE.md,
// "2026-12-04 evening"). Every EXR reader reads RLE (the format's first compression).
// Each scan line is compressed alone and written in order: the bytes do not depend on
// how many threads compress.
inline void set_written_format(Imf::Header& header) {
    header.compression() = Imf::RLE_COMPRESSION;
    header.lineOrder() = Imf::INCREASING_Y;
}

}  // namespace aliquot
