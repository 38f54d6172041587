// OpenEXR reading and writing through Imf::OutputFile / Imf::InputFile.
#include "exr_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfTileDescriptionAttribute.h>
#include <OpenEXR/ImfVersion.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <system_error>
#include <thread>

#include "aov_channels.h"
#include "exr_format.h"

namespace aliquot {
namespace {

constexpr const char* kRgb[3] = {"R", "G", "B"};
// Twice the largest side the farm renders: larger claims are refused before allocating.
constexpr int64_t kMaxSide = 16384;
// R, G, B and every AOV the farm writes, with room to spare.
constexpr size_t kMaxChannels = 16;
// String attributes kept when reading, and the longest kept: what the farm writes, with
// room to spare; a file's header cannot make a reader hold more.
constexpr size_t kMaxAttributes = 64;
constexpr size_t kMaxAttributeBytes = 64 * 1024;

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
    for (const auto& [name, value] : image.attributes) {
        const size_t colon = name.find(':');
        if (colon == std::string::npos || colon == 0 || colon + 1 == name.size())
            fail("write", path,
                 "attribute name '" + name + "' is not of the form namespace:name");
        if (value.size() > kMaxAttributeBytes)
            fail("write", path, "attribute '" + name + "' is longer than 64 KiB");
    }
    if (image.attributes.size() > kMaxAttributes)
        fail("write", path,
             "more than " + std::to_string(kMaxAttributes) + " attributes");
}

// Grows OpenEXR's pool to at least `threads` (it starts with none, and then compressed a
// 2048x2048 render's 48 MB on one core for 1.4 s of a 3.3 s process). Never shrunk:
// shrinking waits for the files other threads are writing.
void reserve_pool(int threads) {
    static std::mutex mutex;
    static int pool = 0;
    std::lock_guard lock(mutex);
    if (threads <= pool) return;
    Imf::setGlobalThreadCount(threads);
    pool = threads;
}

// Writes `image` to an OpenEXR stream (a file or memory): the one writer of both.
void write_to(Imf::OStream& stream, const Image& image, int threads) {
    // The header holds only the fixed attributes: no dates or software names, so the same
    // Image always gives the same bytes (tests compare files produced by different runs).
    Imf::Header header(int(image.width), int(image.height));
    set_written_format(header);
    // The image's own attributes (a render's spec): deterministic by construction, and
    // written in name order whatever order they were set in.
    for (const auto& [name, value] : image.attributes)
        header.insert(name, Imf::StringAttribute(value));

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

    threads = std::max(threads, 0);
    if (threads > 0) reserve_pool(threads);
    Imf::OutputFile file(stream, header, threads);
    file.setFrameBuffer(frame);
    file.writePixels(int(image.height));
}

std::string mib(uint64_t bytes) { return std::to_string(bytes >> 20) + " MiB"; }

// The header alone, read before any pixel is: what it claims decides whether the pixels
// are read at all. (Opening an Imf::InputFile already sizes its buffers by the header.)
Imf::Header read_header(Imf::IStream& stream, const std::filesystem::path& path) {
    char start[8];
    stream.read(start, sizeof start);
    int version =  // readFrom takes it by reference
        int(uint32_t(uint8_t(start[4])) | uint32_t(uint8_t(start[5])) << 8 |
            uint32_t(uint8_t(start[6])) << 16 | uint32_t(uint8_t(start[7])) << 24);
    if (Imf::isMultiPart(version) || Imf::isNonImage(version))
        fail("read", path, "only single-part images are read (no multi-part, no deep)");
    Imf::Header header;
    header.readFrom(stream, version);
    stream.seekg(0);
    return header;
}

// How many bytes OpenEXR reads for a value of a fixed-size type whatever size the file
// states (0: not such a type).
size_t fixed_value_size(const std::string& type) {
    static const std::map<std::string, size_t> kSizes = {
        {"box2i", 16},    {"box2f", 16},   {"compression", 1},
        {"lineOrder", 1}, {"envmap", 1},   {"float", 4},
        {"int", 4},       {"double", 8},   {"rational", 8},
        {"v2i", 8},       {"v2f", 8},      {"v2d", 16},
        {"v3i", 12},      {"v3f", 12},     {"v3d", 24},
        {"m33f", 36},     {"m33d", 72},    {"m44f", 64},
        {"m44d", 128},    {"keycode", 28}, {"chromaticities", 32},
        {"timecode", 8},  {"tiledesc", 9}, {"deepImageState", 1}};
    const auto it = kSizes.find(type);
    return it == kSizes.end() ? 0 : it->second;
}

// Refuses a header OpenEXR would read past what the bytes hold, before it reads it:
// OpenEXR allocates what an attribute claims before reading it (a string is even zeroed
// first), so 2 KB claiming a 1.9 GB attribute took 1.9 GB. The header is a list of
// (name, type, 32-bit size, value) ended by an empty name. Every value must lie within
// the bytes; types OpenEXR reads by their content rather than by the stated size must
// state the size their content takes (so that this reading and OpenEXR's stay in step);
// those whose content claims further allocations (previews, string vectors, ID
// manifests) are refused: no image of ours has them.
void check_header_claims(const std::string& bytes, const std::filesystem::path& path) {
    const auto cut_short = [&] { fail("read", path, "the header is cut short"); };
    const auto read_int = [&](size_t at) {
        return int32_t(uint32_t(uint8_t(bytes[at])) |
                       uint32_t(uint8_t(bytes[at + 1])) << 8 |
                       uint32_t(uint8_t(bytes[at + 2])) << 16 |
                       uint32_t(uint8_t(bytes[at + 3])) << 24);
    };
    size_t at = 8;  // past the magic number and the version
    const auto read_string = [&] {
        const size_t end = bytes.find('\0', at);
        if (end == std::string::npos || end - at > 255) cut_short();
        std::string text = bytes.substr(at, end - at);
        at = end + 1;
        return text;
    };
    for (;;) {
        const std::string name = read_string();
        if (name.empty()) return;  // the empty name that ends the header
        const std::string type = read_string();
        if (bytes.size() - at < 4) cut_short();
        const int32_t size = read_int(at);
        at += 4;
        if (size < 0 || uint64_t(size) > bytes.size() - at)
            fail("read", path,
                 "attribute " + name + " claims " + std::to_string(size) +
                     " bytes, more than follow it");
        const size_t end = at + size_t(size);
        const size_t fixed = fixed_value_size(type);
        bool in_step = fixed == 0 || fixed == size_t(size);
        if (type == "chlist") {
            // Channels (a name, then 16 bytes) up to an empty name, as OpenEXR reads
            // them.
            size_t c = at;
            while (in_step && c < end && bytes[c] != '\0') {
                const size_t name_end = bytes.find('\0', c);
                in_step = name_end != std::string::npos && name_end - c <= 255 &&
                          name_end + 17 <= end;
                c = name_end + 17;
            }
            in_step = in_step && c + 1 == end;
        } else if (type == "preview" || type == "stringvector" || type == "idmanifest") {
            fail("read", path, "attribute " + name + " of type " + type + " is not read");
        }
        if (!in_step)
            fail("read", path,
                 "attribute " + name + " of type " + type + " states " +
                     std::to_string(size) + " bytes, not what its value takes");
        at = end;
    }
}

// Refuses what the header claims before anything is allocated by it: a few kilobytes
// (or a few megabytes of ZIP) can claim gigabytes of pixels.
void check_claims(const Imf::Header& header, const std::filesystem::path& path,
                  const ExrSize* expected, uint64_t max_bytes) {
    const Imath::Box2i dw = header.dataWindow();
    const int64_t w = int64_t(dw.max.x) - dw.min.x + 1;
    const int64_t h = int64_t(dw.max.y) - dw.min.y + 1;
    if (w < 1 || h < 1 || w > kMaxSide || h > kMaxSide)
        fail("read", path,
             "data window " + std::to_string(w) + "x" + std::to_string(h) +
                 " is outside 1.." + std::to_string(kMaxSide) + " a side");
    if (expected && (w != expected->width || h != expected->height))
        fail("read", path,
             "it is " + std::to_string(w) + "x" + std::to_string(h) + ", expected " +
                 std::to_string(expected->width) + "x" +
                 std::to_string(expected->height));
    const Imf::ChannelList& channels = header.channels();
    size_t channel_count = 0;
    for (auto it = channels.begin(); it != channels.end(); ++it) ++channel_count;
    // Each channel is a full float plane: the count is bounded as the size is.
    if (channel_count > kMaxChannels)
        fail("read", path,
             std::to_string(channel_count) + " channels, more than " +
                 std::to_string(kMaxChannels));
    const uint64_t pixel_bytes =
        uint64_t(w) * uint64_t(h) * channel_count * sizeof(float);
    if (max_bytes > 0 && pixel_bytes > max_bytes)
        throw ImageTooLarge("cannot read " + path.string() + ": " +
                            std::to_string(channel_count) + " channels of " +
                            std::to_string(w) + "x" + std::to_string(h) + " take " +
                            mib(pixel_bytes) + " decoded, more than " + mib(max_bytes) +
                            " the memory budget leaves for it");
    // A tiled file's reader holds a tile's pixels at once: no tile much larger than the
    // image (small images may keep the usual 64x64 tiles, or larger ones up to 256).
    if (header.hasTileDescription()) {
        const Imf::TileDescription& tile = header.tileDescription();
        if (int64_t(tile.xSize) > std::max<int64_t>(w, 256) ||
            int64_t(tile.ySize) > std::max<int64_t>(h, 256))
            fail("read", path,
                 "tiles of " + std::to_string(tile.xSize) + "x" +
                     std::to_string(tile.ySize) + " are larger than the image");
    }
    for (const char* name : kRgb)
        if (!channels.findChannel(name))
            fail("read", path, std::string("no channel ") + name);
    for (auto it = channels.begin(); it != channels.end(); ++it)
        if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
            fail("read", path,
                 std::string("subsampled channel ") + it.name() + " is not supported");
}

// Reads R, G, B and every other channel from an OpenEXR stream; `path` (a file, or what
// the bytes came from) goes into errors. The one reader of files and memory.
Image read_from(Imf::IStream& stream, const std::filesystem::path& path,
                const ExrSize* expected = nullptr, uint64_t max_bytes = 0) {
    check_claims(read_header(stream, path), path, expected, max_bytes);
    // In the calling thread, whatever the pool the writers made: bytes from the network
    // are decoded as the fuzzer decodes them (fuzz/exr_fuzz).
    Imf::InputFile file(stream, 0);
    const Imath::Box2i dw = file.header().dataWindow();
    const int64_t w = int64_t(dw.max.x) - dw.min.x + 1;
    const int64_t h = int64_t(dw.max.y) - dw.min.y + 1;
    const Imf::ChannelList& channels = file.header().channels();

    Image image{uint32_t(w), uint32_t(h)};
    Imf::FrameBuffer frame;
    // Slice::Make offsets the base pointer by the data window origin, which need not
    // be 0.
    for (int c = 0; c < 3; ++c)
        frame.insert(kRgb[c], Imf::Slice::Make(Imf::FLOAT, image.rgb.data() + c, dw,
                                               3 * sizeof(float), 3 * sizeof(float) * w));
    // ChannelList iterates by name, so extras come back sorted, whatever order was
    // written.
    std::vector<std::string> file_names;  // as in the file, for the frame buffer
    for (auto it = channels.begin(); it != channels.end(); ++it) {
        const std::string name = it.name();
        if (name == "R" || name == "G" || name == "B") continue;
        file_names.push_back(name);
        image.extra.push_back(
            {current_channel_name(name), std::vector<float>(image.pixel_count())});
    }
    for (size_t i = 0; i < image.extra.size(); ++i)
        frame.insert(file_names[i],
                     Imf::Slice::Make(Imf::FLOAT, image.extra[i].values.data(), dw,
                                      sizeof(float), sizeof(float) * w));
    // A file with both an old and a new name of one channel would now hold it twice.
    std::set<std::string> seen;
    for (const Image::Channel& ch : image.extra)
        if (!seen.insert(ch.name).second)
            fail("read", path, "channel " + ch.name + " appears twice");
    const Imf::Header& header = file.header();
    for (auto it = header.begin(); it != header.end(); ++it) {
        // By type name, not dynamic_cast: RTTI across the shared library is not to be
        // relied on for templates.
        if (std::strcmp(it.attribute().typeName(), "string") != 0 ||
            std::string(it.name()).find(':') == std::string::npos)
            continue;
        const auto* text = static_cast<const Imf::StringAttribute*>(&it.attribute());
        if (image.attributes.size() == kMaxAttributes) break;
        if (text->value().size() <= kMaxAttributeBytes)
            image.attributes[it.name()] = text->value();
    }
    file.setFrameBuffer(frame);
    file.readPixels(dw.min.y, dw.max.y);
    return image;
}

// Turns OpenEXR's and the library's exceptions into one ImageFileError naming `name`.
template <typename F>
Image reading(const std::filesystem::path& name, F&& read) {
    try {
        return read();
    } catch (const ImageFileError&) {
        throw;
    } catch (const std::exception& e) {
        fail("read", name, e.what());
    }
}

}  // namespace

int exr_write_threads() {
    static const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
    return threads;
}

void write_exr(const std::filesystem::path& path, const Image& image, int threads) {
    check_writable(path, image);
    // Opening the stream ourselves gives errno, hence a plain "No such file or directory"
    // instead of OpenEXR's longer message.
    std::ofstream os(path, std::ios::binary | std::ios::trunc);
    if (!os) fail("write", path, std::strerror(errno));
    try {
        Imf::StdOFStream stream(os, path.string().c_str());
        write_to(stream, image, threads);
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
    return reading(path, [&] {
        Imf::StdIFStream stream(is, path.string().c_str());
        return read_from(stream, path);
    });
}

std::string encode_exr(const Image& image, int threads) {
    const std::filesystem::path name = "image in memory";
    check_writable(name, image);
    try {
        Imf::StdOSStream stream;
        write_to(stream, image, threads);
        return stream.str();
    } catch (const std::exception& e) {
        fail("write", name, e.what());
    }
}

Image decode_exr(const std::string& bytes, const std::string& name,
                 std::optional<ExrSize> expected, uint64_t max_bytes) {
    if (bytes.size() < 8 || !Imf::isImfMagic(bytes.data()))
        fail("read", name, "not an OpenEXR file");
    check_header_claims(bytes, name);
    return reading(name, [&] {
        Imf::StdISStream stream;
        stream.str(bytes);
        return read_from(stream, name, expected ? &*expected : nullptr, max_bytes);
    });
}

}  // namespace aliquot
