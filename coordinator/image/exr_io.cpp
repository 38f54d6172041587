// OpenEXR reading and writing through Imf::OutputFile / Imf::InputFile.
#include "exr_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfVersion.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>
#include <string>
#include <system_error>

namespace aliquot {
namespace {

constexpr const char* kRgb[3] = {"R", "G", "B"};

[[noreturn]] void fail(const char* verb, const std::filesystem::path& path,
                       const std::string& why) {
    throw ImageFileError("cannot " + std::string(verb) + " " + path.string() + ": " +
                         why);
}

void check_writable(const std::filesystem::path& path, const Image& image) {
    // EXR cannot represent an empty data window.
    if (image.width == 0 || image.height == 0) fail("write", path, "image is empty");
    if (image.rgb.size() != image.pixel_count() * 3)
        fail("write", path,
             "rgb holds " + std::to_string(image.rgb.size()) + " floats, expected " +
                 std::to_string(image.pixel_count() * 3));
    std::set<std::string> names(std::begin(kRgb), std::end(kRgb));
    for (const Image::Channel& c : image.extra) {
        if (c.name.empty() || !names.insert(c.name).second)
            fail("write", path, "channel name '" + c.name + "' is empty or repeated");
        if (c.values.size() != image.pixel_count())
            fail("write", path,
                 "channel '" + c.name + "' holds " + std::to_string(c.values.size()) +
                     " values, expected " + std::to_string(image.pixel_count()));
    }
}

}  // namespace

void write_exr(const std::filesystem::path& path, const Image& image) {
    check_writable(path, image);

    // The header holds only the fixed attributes: no dates or software names, so the same
    // Image always gives the same bytes (tests compare files produced by different runs).
    Imf::Header header(int(image.width), int(image.height));
    header.compression() = Imf::ZIP_COMPRESSION;
    header.lineOrder() = Imf::INCREASING_Y;

    const size_t w = image.width;
    Imf::FrameBuffer frame;
    for (int c = 0; c < 3; ++c) {
        header.channels().insert(kRgb[c], Imf::Channel(Imf::FLOAT));
        // Slices only read from the pointer; the API takes char* for both directions.
        char* base = reinterpret_cast<char*>(const_cast<float*>(image.rgb.data() + c));
        frame.insert(kRgb[c], Imf::Slice(Imf::FLOAT, base, 3 * sizeof(float),
                                         3 * sizeof(float) * w));
    }
    for (const Image::Channel& ch : image.extra) {
        header.channels().insert(ch.name, Imf::Channel(Imf::FLOAT));
        char* base = reinterpret_cast<char*>(const_cast<float*>(ch.values.data()));
        frame.insert(ch.name,
                     Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * w));
    }

    // Opening the stream ourselves gives errno, hence a plain "No such file or directory"
    // instead of OpenEXR's longer message.
    std::ofstream os(path, std::ios::binary | std::ios::trunc);
    if (!os) fail("write", path, std::strerror(errno));
    try {
        Imf::StdOFStream stream(os, path.string().c_str());
        Imf::OutputFile file(stream, header);
        file.setFrameBuffer(frame);
        file.writePixels(int(image.height));
    } catch (const std::exception& e) {
        os.close();
        std::error_code ignored;
        std::filesystem::remove(path,
                                ignored);  // a half-written file would look valid by name
        fail("write", path, e.what());
    }
    // The line offset table is written by ~OutputFile, so a full disk shows up only here.
    os.close();
    if (!os) {
        std::error_code ignored;
        std::filesystem::remove(path, ignored);
        fail("write", path, "write failed");
    }
}

Image read_exr(const std::filesystem::path& path) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        fail("read", path, std::strerror(EISDIR));
    std::ifstream is(path, std::ios::binary);
    if (!is) fail("read", path, std::strerror(errno));
    char magic[4] = {};
    if (!is.read(magic, 4) || !Imf::isImfMagic(magic))
        fail("read", path, "not an OpenEXR file");
    is.seekg(0);

    try {
        Imf::StdIFStream stream(is, path.string().c_str());
        Imf::InputFile file(stream);
        const Imath::Box2i dw = file.header().dataWindow();
        const int64_t w = int64_t(dw.max.x) - dw.min.x + 1;
        const int64_t h = int64_t(dw.max.y) - dw.min.y + 1;
        const Imf::ChannelList& channels = file.header().channels();
        for (const char* name : kRgb)
            if (!channels.findChannel(name))
                fail("read", path, std::string("no channel ") + name);
        for (auto it = channels.begin(); it != channels.end(); ++it)
            if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
                fail(
                    "read", path,
                    std::string("subsampled channel ") + it.name() + " is not supported");

        Image image{uint32_t(w), uint32_t(h)};
        Imf::FrameBuffer frame;
        // Slice::Make offsets the base pointer by the data window origin, which need not
        // be 0.
        for (int c = 0; c < 3; ++c)
            frame.insert(kRgb[c],
                         Imf::Slice::Make(Imf::FLOAT, image.rgb.data() + c, dw,
                                          3 * sizeof(float), 3 * sizeof(float) * w));
        // ChannelList iterates by name, so extras come back sorted, whatever order was
        // written.
        for (auto it = channels.begin(); it != channels.end(); ++it) {
            const std::string name = it.name();
            if (name == "R" || name == "G" || name == "B") continue;
            image.extra.push_back({name, std::vector<float>(image.pixel_count())});
        }
        for (Image::Channel& ch : image.extra)
            frame.insert(ch.name, Imf::Slice::Make(Imf::FLOAT, ch.values.data(), dw,
                                                   sizeof(float), sizeof(float) * w));
        file.setFrameBuffer(frame);
        file.readPixels(dw.min.y, dw.max.y);
        return image;
    } catch (const ImageFileError&) {
        throw;
    } catch (const std::exception& e) {
        fail("read", path, e.what());
    }
}

}  // namespace aliquot
