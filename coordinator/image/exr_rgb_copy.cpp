#include "exr_rgb_copy.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <vector>

#include "exr_format.h"
#include "exr_io.h"

namespace aliquot {

namespace {

constexpr const char* kRgb[3] = {"R", "G", "B"};
// Rows per band: 64 rows of an 8192-wide image are 6 MiB of floats.
constexpr int kBandRows = 64;

[[noreturn]] void fail(const std::filesystem::path& path, const std::string& why) {
    throw ImageFileError("cannot copy " + path.string() + ": " + why);
}

// The band's R, G, B interleaved, as write_exr's frame buffer has them, addressed by the
// rows [y0, y0 + rows) of a data window starting at column x0.
Imf::FrameBuffer band_frame(std::vector<float>& band, int x0, int y0, int width,
                            int rows) {
    const Imath::Box2i box({x0, y0}, {x0 + width - 1, y0 + rows - 1});
    Imf::FrameBuffer frame;
    for (int c = 0; c < 3; ++c)
        frame.insert(kRgb[c],
                     Imf::Slice::Make(Imf::FLOAT, band.data() + c, box, 3 * sizeof(float),
                                      3 * sizeof(float) * size_t(width)));
    return frame;
}

void copy(const std::filesystem::path& from, std::ofstream& os,
          const std::filesystem::path& to) {
    std::ifstream is(from, std::ios::binary);
    if (!is) fail(from, std::strerror(errno));
    Imf::StdIFStream in_stream(is, from.string().c_str());
    Imf::InputFile in(in_stream);
    const Imath::Box2i dw = in.header().dataWindow();
    const int width = dw.max.x - dw.min.x + 1, height = dw.max.y - dw.min.y + 1;
    for (const char* name : kRgb)
        if (!in.header().channels().findChannel(name))
            fail(from, std::string("no channel ") + name);

    // As write_exr makes it: the fixed attributes and the image's own, nothing else.
    Imf::Header header(width, height);
    set_written_format(header);
    for (auto it = in.header().begin(); it != in.header().end(); ++it)
        if (std::strcmp(it.attribute().typeName(), "string") == 0 &&
            std::strchr(it.name(), ':'))
            header.insert(it.name(), it.attribute());
    for (const char* name : kRgb)
        header.channels().insert(name, Imf::Channel(Imf::FLOAT));

    Imf::StdOFStream out_stream(os, to.string().c_str());
    Imf::OutputFile out(out_stream, header);
    std::vector<float> band(size_t(width) * kBandRows * 3);
    for (int y = 0; y < height; y += kBandRows) {
        const int rows = std::min(kBandRows, height - y);
        in.setFrameBuffer(band_frame(band, dw.min.x, dw.min.y + y, width, rows));
        in.readPixels(dw.min.y + y, dw.min.y + y + rows - 1);
        out.setFrameBuffer(band_frame(band, 0, y, width, rows));
        out.writePixels(rows);
    }
}

}  // namespace

void copy_exr_rgb(const std::filesystem::path& from, const std::filesystem::path& to) {
    std::ofstream os(to, std::ios::binary | std::ios::trunc);
    if (!os) fail(to, std::strerror(errno));
    std::string error;
    try {
        copy(from, os, to);  // the line offset table is written as `out` closes
    } catch (const ImageFileError& e) {
        error = e.what();
    } catch (const std::exception& e) {
        error = "cannot copy " + from.string() + ": " + e.what();
    }
    os.close();
    if (error.empty() && !os) error = "cannot write " + to.string();
    if (!error.empty()) {
        std::error_code ignored;
        std::filesystem::remove(to, ignored);
        throw ImageFileError(error);
    }
}

}  // namespace aliquot
