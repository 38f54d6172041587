// OpenEXR I/O: round trips, deterministic bytes, and errors that name the file.
#include "exr_io.h"

#include "aov_channels.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfThreading.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

namespace aliquot {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test, so tests can run in parallel (ctest -j) without sharing
// files.
class ExrIo : public testing::Test {
protected:
    void SetUp() override {
        dir = fs::temp_directory_path() /
              ("aliquot_exr_" + std::to_string(getpid()) + "_" +
               testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir);
        fs::create_directories(dir);
    }
    void TearDown() override { fs::remove_all(dir); }
    fs::path dir;
};

Image patterned(uint32_t w, uint32_t h) {
    Image image(w, h);
    for (size_t i = 0; i < image.rgb.size(); ++i)
        image.rgb[i] = 0.25f * float(i % 97) - 3.0f;
    image.extra.push_back({kSampleCountChannel, {}});
    image.extra.push_back({kVarianceChannel, {}});
    image.attributes = {{"aliquot:seed", "7"}, {"aliquot:method", "uniform"}};
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        image.extra[0].values.push_back(float(i % 4096));
        image.extra[1].values.push_back(1e-6f * float(i));
    }
    return image;
}

std::string bytes_of(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

void expect_same(const Image& a, const Image& b) {
    ASSERT_EQ(a.width, b.width);
    ASSERT_EQ(a.height, b.height);
    EXPECT_EQ(a.rgb, b.rgb);
    ASSERT_EQ(a.extra.size(), b.extra.size());
    for (size_t i = 0; i < a.extra.size(); ++i) {
        EXPECT_EQ(a.extra[i].name, b.extra[i].name);
        EXPECT_EQ(a.extra[i].values, b.extra[i].values);
    }
    EXPECT_EQ(a.attributes, b.attributes);
}

TEST_F(ExrIo, RoundTripKeepsRgbAndExtraChannelsAtOddSize) {
    const Image image = patterned(601, 377);
    write_exr(dir / "a.exr", image);
    expect_same(read_exr(dir / "a.exr"), image);
}

TEST_F(ExrIo, RoundTripKeepsOnePixelImage) {
    const Image image = patterned(1, 1);
    write_exr(dir / "a.exr", image);
    expect_same(read_exr(dir / "a.exr"), image);
}

TEST_F(ExrIo, ExtraChannelsComeBackSortedByName) {
    Image image(2, 2);
    image.extra = {{kVarianceChannel, {1, 2, 3, 4}}, {kSampleCountChannel, {5, 6, 7, 8}}};
    write_exr(dir / "a.exr", image);
    const Image back = read_exr(dir / "a.exr");
    ASSERT_EQ(back.extra.size(), 2u);
    EXPECT_EQ(back.extra[0].name, kSampleCountChannel);
    EXPECT_EQ(back.extra[0].values, (std::vector<float>{5, 6, 7, 8}));
    EXPECT_EQ(back.extra[1].name, kVarianceChannel);
}

TEST_F(ExrIo, ChannelsOfOlderFilesAreReadUnderTheirLayerNames) {
    Image image(2, 1);
    image.extra = {{"spp", {3, 4}}, {"variance", {0.5f, 0.25f}}};
    write_exr(dir / "old.exr", image);
    const Image back = read_exr(dir / "old.exr");
    ASSERT_EQ(back.extra.size(), 2u);
    EXPECT_EQ(back.extra[0].name, kSampleCountChannel);
    EXPECT_EQ(back.extra[0].values, (std::vector<float>{3, 4}));
    EXPECT_EQ(back.extra[1].name, kVarianceChannel);
}

TEST_F(ExrIo, AFileWithAChannelUnderBothNamesIsRefused) {
    Image image(1, 1);
    image.extra = {{"spp", {1}}, {kSampleCountChannel, {1}}};
    write_exr(dir / "both.exr", image);
    EXPECT_THROW(read_exr(dir / "both.exr"), ImageFileError);
}

TEST_F(ExrIo, AttributesRoundTripAndTheirOrderDoesNotChangeTheBytes) {
    Image a(3, 2), b(3, 2);
    a.attributes["aliquot:seed"] = "18446744073709551615";
    a.attributes["aliquot:strategy"] = R"({"method":"uniform","spp":4})";
    b.attributes["aliquot:strategy"] = R"({"method":"uniform","spp":4})";
    b.attributes["aliquot:seed"] = "18446744073709551615";
    EXPECT_EQ(encode_exr(a), encode_exr(b));
    EXPECT_EQ(decode_exr(encode_exr(a), "a").attributes, a.attributes);
}

TEST_F(ExrIo, AttributesOutsideANamespaceOrTooLongAreRefused) {
    for (const std::string name : {"seed", ":seed", "aliquot:", "channels"}) {
        Image image(1, 1);
        image.attributes[name] = "x";
        EXPECT_THROW(encode_exr(image), ImageFileError) << name;
    }
    Image image(1, 1);
    image.attributes["aliquot:long"] = std::string(64 * 1024 + 1, 'x');
    EXPECT_THROW(encode_exr(image), ImageFileError);
}

TEST_F(ExrIo, SameImageGivesIdenticalBytes) {
    const Image image = patterned(64, 48);
    write_exr(dir / "a.exr", image);
    write_exr(dir / "b.exr", image);
    const std::string a = bytes_of(dir / "a.exr");
    EXPECT_FALSE(a.empty());
    EXPECT_EQ(a, bytes_of(dir / "b.exr"));
}

TEST_F(ExrIo, TheBytesDoNotDependOnHowManyThreadsCompress) {
    // Many blocks (a scan line each), so that threads take different ones.
    const Image image = patterned(67, 203);
    const std::string alone = encode_exr(image, 0);
    for (int threads : {1, 2, 4, 7})
        EXPECT_EQ(encode_exr(image, threads), alone) << threads << " threads";
    EXPECT_EQ(encode_exr(image), alone);
    // Written by default with OpenEXR's pool, which has one thread per hardware thread.
    EXPECT_GE(Imf::globalThreadCount(), exr_write_threads());
    write_exr(dir / "a.exr", image, 4);
    EXPECT_EQ(bytes_of(dir / "a.exr"), alone);
    expect_same(decode_exr(alone, "alone"), image);
}

// Issue 33: ZIP's zlib was ~0.4 CPU s of a 1920x1080 render's end, about 1 % of a
// 64-spp render's worker CPU; RLE costs a fifth of it for files a quarter larger.
TEST_F(ExrIo, WritesRleCompressedScanLinesInOrder) {
    Imf::StdISStream stream;
    stream.str(encode_exr(patterned(9, 5)));
    Imf::InputFile file(stream, 0);
    EXPECT_EQ(file.header().compression(), Imf::RLE_COMPRESSION);
    EXPECT_EQ(file.header().lineOrder(), Imf::INCREASING_Y);
    EXPECT_FALSE(file.header().hasTileDescription());
}

TEST_F(ExrIo, WritingIntoMissingDirectoryNamesThePath) {
    const fs::path path = dir / "missing" / "x.exr";
    try {
        write_exr(path, Image(4, 4));
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_EQ(std::string(e.what()),
                  "cannot write " + path.string() + ": No such file or directory");
    }
}

TEST_F(ExrIo, WritingChannelWithWrongValueCountFails) {
    Image image(4, 4);
    image.extra.push_back({kSampleCountChannel, {1, 2, 3}});
    EXPECT_THROW(write_exr(dir / "a.exr", image), ImageFileError);
}

TEST_F(ExrIo, ReadingMissingFileNamesThePath) {
    const fs::path path = dir / "nope.exr";
    try {
        read_exr(path);
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_EQ(std::string(e.what()),
                  "cannot read " + path.string() + ": No such file or directory");
    }
}

TEST_F(ExrIo, ReadingNonExrFileFails) {
    std::ofstream(dir / "a.exr") << "P3\n1 1\n255\n0 0 0\n";
    try {
        read_exr(dir / "a.exr");
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_EQ(std::string(e.what()),
                  "cannot read " + (dir / "a.exr").string() + ": not an OpenEXR file");
    }
}

TEST_F(ExrIo, ReadingTruncatedFileFailsWithItsPath) {
    write_exr(dir / "a.exr", patterned(32, 32));
    const std::string bytes = bytes_of(dir / "a.exr");
    std::ofstream(dir / "cut.exr", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    try {
        read_exr(dir / "cut.exr");
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_EQ(
            std::string(e.what()).rfind("cannot read " + (dir / "cut.exr").string(), 0),
            0u)
            << e.what();
    }
}

// Files from other tools: a data window away from the origin, half floats, no B channel.
// Every channel holds 0, 1, 2, ... (exact in half); returns those values as floats.
std::vector<float> write_foreign(const fs::path& path, const Imath::Box2i& window,
                                 std::initializer_list<const char*> names) {
    Imf::Header header(window, window);
    const int w = window.max.x - window.min.x + 1, h = window.max.y - window.min.y + 1;
    std::vector<half> data(size_t(w) * h);
    for (size_t i = 0; i < data.size(); ++i) data[i] = half(float(i));
    Imf::FrameBuffer frame;
    for (const char* name : names) {
        header.channels().insert(name, Imf::Channel(Imf::HALF));
        frame.insert(name, Imf::Slice::Make(Imf::HALF, data.data(), window));
    }
    Imf::OutputFile file(path.string().c_str(), header);
    file.setFrameBuffer(frame);
    file.writePixels(h);
    return std::vector<float>(data.begin(), data.end());
}

TEST_F(ExrIo, ReadsDataWindowThatDoesNotStartAtZero) {
    const std::vector<float> data = write_foreign(
        dir / "a.exr", Imath::Box2i({10, 20}, {14, 22}), {"R", "G", "B", "Z"});
    const Image image = read_exr(dir / "a.exr");
    ASSERT_EQ(image.width, 5u);
    ASSERT_EQ(image.height, 3u);
    for (size_t i = 0; i < data.size(); ++i) {
        EXPECT_EQ(image.rgb[3 * i], data[i]);
        EXPECT_EQ(image.rgb[3 * i + 2], data[i]);
    }
    ASSERT_EQ(image.extra.size(), 1u);
    EXPECT_EQ(image.extra[0].name, "Z");
    EXPECT_EQ(image.extra[0].values, data);
}

TEST_F(ExrIo, ReadingFileWithoutBlueChannelFails) {
    write_foreign(dir / "a.exr", Imath::Box2i({0, 0}, {3, 3}), {"R", "G"});
    try {
        read_exr(dir / "a.exr");
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_EQ(std::string(e.what()),
                  "cannot read " + (dir / "a.exr").string() + ": no channel B");
    }
}

TEST_F(ExrIo, AHeaderClaimingAHugeImageIsRefusedBeforeAllocating) {
    write_foreign(dir / "wide.exr", Imath::Box2i({0, 0}, {99999, 0}), {"R", "G", "B"});
    try {
        read_exr(dir / "wide.exr");
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_NE(std::string(e.what()).find("100000x1 is outside 1..16384"),
                  std::string::npos)
            << e.what();
    }
}

TEST_F(ExrIo, EncodingInMemoryGivesTheFilesBytesAndDecodesBack) {
    const Image image = patterned(33, 17);
    write_exr(dir / "a.exr", image);
    const std::string bytes = encode_exr(image);
    EXPECT_EQ(bytes, bytes_of(dir / "a.exr"));
    expect_same(decode_exr(bytes, "upload"), image);
}

TEST_F(ExrIo, DecodingBadBytesNamesTheirSource) {
    const std::string bytes = encode_exr(patterned(32, 32));
    for (const std::string& bad :
         {std::string("not an exr"), bytes.substr(0, bytes.size() / 2)}) {
        try {
            decode_exr(bad, "the reference");
            FAIL() << "expected ImageFileError";
        } catch (const ImageFileError& e) {
            EXPECT_EQ(std::string(e.what()).rfind("cannot read the reference: ", 0), 0u)
                << e.what();
        }
    }
}

// Found in review: a few kilobytes of header could claim 16384x16384 and any number of
// channels, and decoding allocated every plane before failing. A caller that knows the
// size passes it; the channel count is bounded for everyone.
TEST_F(ExrIo, BytesOfAnotherSizeOrTooManyChannelsAreRefusedBeforeAllocating) {
    const std::string bytes = encode_exr(patterned(8, 8));
    EXPECT_NO_THROW(decode_exr(bytes, "ref", ExrSize{8, 8}));
    try {
        decode_exr(bytes, "ref", ExrSize{16, 16});
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_NE(std::string(e.what()).find("it is 8x8, expected 16x16"),
                  std::string::npos)
            << e.what();
    }
    Image many(4, 4);
    for (int c = 0; c < 14; ++c)
        many.extra.push_back({"c" + std::to_string(c), std::vector<float>(16, 0.0f)});
    EXPECT_THROW(decode_exr(encode_exr(many), "ref"), ImageFileError);
}

// Issue 30, item 6: a valid 3.8 MB ZIP EXR of 8192x8192 with 14 channels, submitted as a
// reference under --memory-limit 2G, was decoded (3.6 GB, 28 s of CPU) before the budget
// refused the render. Its header alone now decides: these bytes are that header with no
// pixels behind it, which a decoder reaching the pixels would have allocated 3.5 GiB for
// (the planes are made before they are read) and then failed on.
TEST_F(ExrIo, AHeaderClaimingMoreThanTheBudgetIsRefusedBeforeAnyPixel) {
    Imf::Header header(8192, 8192);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const char* name : {"R", "G", "B", "A", "Z", "N.X", "N.Y", "N.Z", "albedo.R",
                             "albedo.G", "albedo.B", "sampleCount.Y", "variance.Y", "id"})
        header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    Imf::StdOSStream out;
    { Imf::OutputFile file(out, header); }  // the header and an empty offset table
    const std::string bytes = out.str();
    ASSERT_LT(bytes.size(), 64u * 1024);
    rusage before{};
    getrusage(RUSAGE_SELF, &before);
    try {
        decode_exr(bytes, "ref", ExrSize{8192, 8192}, uint64_t(2) << 30);
        FAIL() << "expected ImageTooLarge";
    } catch (const ImageTooLarge& e) {
        EXPECT_NE(std::string(e.what()).find("14 channels of 8192x8192 take 3584 MiB "
                                             "decoded, more than 2048 MiB"),
                  std::string::npos)
            << e.what();
    }
    rusage after{};
    getrusage(RUSAGE_SELF, &after);
    EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "KiB more at the peak";
    // Exactly at the bound a small image decodes; a byte less and it does not.
    const Image small = patterned(64, 64);
    EXPECT_NO_THROW(
        decode_exr(encode_exr(small), "ref", ExrSize{64, 64}, 64 * 64 * 5 * 4));
    EXPECT_THROW(
        decode_exr(encode_exr(small), "ref", ExrSize{64, 64}, 64 * 64 * 5 * 4 - 1),
        ImageTooLarge);
}

// Found by fuzz/exr_fuzz: OpenEXR allocates the size an attribute claims before reading
// it, so 2 KB whose header claimed a 1.9 GB attribute allocated 1.9 GB (and any number of
// such attributes, each). An attribute claiming more bytes than follow it is refused.
TEST_F(ExrIo, AnAttributeClaimingMoreBytesThanFollowIsRefusedBeforeAllocating) {
    std::string bytes = encode_exr(patterned(4, 4));
    const std::string key("aliquot:method\0string\0", 22);
    const size_t at = bytes.find(key);
    ASSERT_NE(at, std::string::npos);
    const int32_t claim = 1900000000;
    std::memcpy(&bytes[at + key.size()], &claim, sizeof claim);  // little-endian
    rusage before{};
    getrusage(RUSAGE_SELF, &before);
    try {
        decode_exr(bytes, "ref");
        FAIL() << "expected ImageFileError";
    } catch (const ImageFileError& e) {
        EXPECT_NE(
            std::string(e.what()).find(
                "attribute aliquot:method claims 1900000000 bytes, more than follow"),
            std::string::npos)
            << e.what();
    }
    rusage after{};
    getrusage(RUSAGE_SELF, &after);
    EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "KiB more at the peak";
}

}  // namespace
}  // namespace aliquot
