// The job and result messages' mapping, its version check (issue 34's first-hit sums)
// and the records version 2 carries a result's sums in (issue 33).
#include "wire.h"

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>

#include "sum_records.h"

namespace aliquot {
namespace {

SampleJobResult two_pixel_result(bool aux) {
    SampleJobResult r;
    r.rect = {3, 4, 2, 1};
    r.pixels.resize(2);
    r.pixels[0] = {{1, 2, 3}, {4, 5, 6}, 7, 2, 9, 0};
    r.pixels[1] = {{0.5, 0.25, 0.125}, {1e-300, 0, 1}, 2, 3, 11, 1};
    if (aux) {
        r.first_hits.resize(2);
        r.first_hits[0] = {{0.4, 0.6, 0.8}, {0, -1, 2}};
        r.first_hits[1] = {{0.1, 0.2, 0.3}, {-0.5, 0.25, 1.5}};
    }
    r.wall_seconds = 0.5;
    return r;
}

// What Complete does: the sums read where the message holds them, nothing copied.
void decode_in_place(const v1::SampleJobResult& message) {
    SampleJobResult result;
    from_proto_in_place(message, result);
}

TEST(Wire, AResultWithFirstHitSumsComesBackTheSame) {
    const SampleJobResult r = two_pixel_result(true);
    v1::SampleJobResult message;
    to_proto(r, message);
    EXPECT_EQ(message.version(), kWireVersion);
    const SampleJobResult back = from_proto(message);
    EXPECT_EQ(back.rect, r.rect);
    EXPECT_EQ(back.pixels, r.pixels);
    EXPECT_EQ(back.first_hits, r.first_hits);
}

TEST(Wire, AResultDecodedInPlaceReadsTheMessagesBytesAndIsTheSame) {
    const SampleJobResult r = two_pixel_result(true);
    v1::SampleJobResult message;
    to_proto(r, message);
    SampleJobResult back;
    from_proto_in_place(message, back);
    EXPECT_EQ(back.rect, r.rect);
    EXPECT_EQ(back.wall_seconds, r.wall_seconds);
    EXPECT_EQ(back.pixels, r.pixels);
    EXPECT_EQ(back.first_hits, r.first_hits);
    const SampleJobResult& read = back;
    EXPECT_EQ(static_cast<const void*>(read.pixels.data()), message.pixels().data());
    EXPECT_EQ(static_cast<const void*>(read.first_hits.data()),
              message.first_hits().data());
    // Decoded again into the same result, now without first hits: none are left.
    message.Clear();
    to_proto(two_pixel_result(false), message);
    from_proto_in_place(message, back);
    EXPECT_TRUE(back.first_hits.empty());
}

// Bytes not aligned for the structs (a buffer of someone else's making) are copied, not
// read where they are.
TEST(Wire, RecordsNotAlignedForTheSumsAreCopied) {
    const SampleJobResult r = two_pixel_result(true);
    std::string records;
    write_records(r.pixels, records);
    const std::string shifted = "x" + records;
    SumsArray<PixelSums> read;
    read_records_in_place(std::string_view(shifted).substr(1), read);
    EXPECT_FALSE(read.borrows());
    EXPECT_EQ(read, r.pixels);
    read_records_in_place(records, read);
    EXPECT_TRUE(read.borrows());
    EXPECT_EQ(read, r.pixels);
}

// A render that is not denoised pays nothing: no first-hit records on the wire.
TEST(Wire, AResultWithoutFirstHitSumsCarriesNone) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(false), message);
    EXPECT_TRUE(message.first_hits().empty());
    const SampleJobResult back = from_proto(message);
    EXPECT_EQ(back.pixels, two_pixel_result(false).pixels);
    EXPECT_TRUE(back.first_hits.empty());
}

// What aliquot.proto says the bytes are, written out by hand: a worker of another
// language or byte order writes these, whatever this machine's struct layout.
TEST(Wire, APixelsRecordIsItsSumsInTheDocumentedOrderLittleEndian) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(true), message);
    ASSERT_EQ(message.pixels().size(), 2 * kPixelRecordBytes);
    ASSERT_EQ(message.first_hits().size(), 2 * kFirstHitRecordBytes);
    const auto u64_at = [](const std::string& bytes, size_t at) {
        uint64_t v = 0;
        for (int b = 0; b < 8; ++b) v |= uint64_t(uint8_t(bytes[at + b])) << (8 * b);
        return v;
    };
    const auto double_at = [&](const std::string& bytes, size_t at) {
        double v;
        const uint64_t bits = u64_at(bytes, at);
        std::memcpy(&v, &bits, 8);
        return v;
    };
    const std::string& p = message.pixels();
    const size_t second =
        kPixelRecordBytes;  // {{0.5, 0.25, 0.125}, {1e-300, 0, 1}, 2, 3, 11, 1}
    EXPECT_EQ(double_at(p, second + 0), 0.5);
    EXPECT_EQ(double_at(p, second + 16), 0.125);
    EXPECT_EQ(double_at(p, second + 24), 1e-300);
    EXPECT_EQ(double_at(p, second + 40), 1);
    EXPECT_EQ(double_at(p, second + 48), 2);
    EXPECT_EQ(u64_at(p, second + 56), 3u);
    EXPECT_EQ(u64_at(p, second + 64), 11u);
    EXPECT_EQ(u64_at(p, second + 72), 1u);
    const std::string& f = message.first_hits();  // {{0.1, 0.2, 0.3}, {-0.5, 0.25, 1.5}}
    EXPECT_EQ(double_at(f, kFirstHitRecordBytes + 8), 0.2);
    EXPECT_EQ(double_at(f, kFirstHitRecordBytes + 24), -0.5);
    EXPECT_EQ(double_at(f, kFirstHitRecordBytes + 40), 1.5);
}

// The field-by-field codec a big-endian machine uses writes and reads the same bytes as
// the one copy this machine uses.
TEST(Wire, TheFieldByFieldRecordsAreTheSameBytes) {
    const SampleJobResult r = two_pixel_result(true);
    const auto same_bytes = [](const auto& records) {
        std::string copied, portable;
        write_records(records, copied);
        portable_records::write_records(records, portable);
        EXPECT_EQ(copied, portable);
        std::decay_t<decltype(records)> read;
        portable_records::read_records(copied, read);
        EXPECT_EQ(read, records);
    };
    same_bytes(r.pixels);
    same_bytes(r.first_hits);
}

// Records short or long by a whole record or a part of one are refused, nothing read.
TEST(Wire, PixelsOfTheWrongLengthAreRefused) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(false), message);
    for (const size_t size :
         {size_t(0), kPixelRecordBytes, 2 * kPixelRecordBytes - 1,
          2 * kPixelRecordBytes + 1, 2 * kPixelRecordBytes + 8, 3 * kPixelRecordBytes}) {
        v1::SampleJobResult wrong = message;
        wrong.mutable_pixels()->resize(size);
        EXPECT_THROW(from_proto(wrong), WireError) << size << " bytes";
        EXPECT_THROW(decode_in_place(wrong), WireError) << size << " bytes";
    }
}

// A rect as large as the wire allows with a few bytes of pixels: refused by its length
// before anything the size of the rect is made (65536 x 65536 x 80 bytes would be 320
// GiB).
TEST(Wire, AHugeRectWithFewRecordsIsRefusedBeforeAnyAllocation) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(false), message);
    message.mutable_rect()->set_width(65536);
    message.mutable_rect()->set_height(65536);
    EXPECT_THROW(from_proto(message), WireError);
    EXPECT_THROW(decode_in_place(message), WireError);
    message.mutable_rect()->set_width(65537);  // beyond any image
    EXPECT_THROW(from_proto(message), WireError);
    EXPECT_THROW(decode_in_place(message), WireError);
    // Width x height that would wrap a 32-bit size: the rect's own bound refuses it.
    message.mutable_rect()->set_width(uint32_t(-1));
    message.mutable_rect()->set_height(uint32_t(-1));
    EXPECT_THROW(from_proto(message), WireError);
    EXPECT_THROW(decode_in_place(message), WireError);
}

TEST(Wire, AJobsAuxFlagComesBackTheSame) {
    SampleJob job;
    job.rect = {0, 0, 1, 2};
    job.counts = {1, 2};
    job.first_sample = {0, 5};
    for (bool aux : {false, true}) {
        job.aux = aux;
        v1::SampleJob message;
        to_proto(job, message);
        EXPECT_EQ(from_proto(message).aux, aux);
    }
}

// A worker from before the first-hit sums sends no version, one from before the records
// version 1: either result is refused whole, with a message that says what to do. (Its
// arrays' fields are reserved: a version 1 result parses, its sums unread.)
TEST(Wire, AResultOfAnOlderVersionIsRefusedWithAClearError) {
    for (const uint32_t old : {0u, 1u}) {
        v1::SampleJobResult message;
        to_proto(two_pixel_result(false), message);
        message.set_version(old);
        try {
            from_proto(message);
            FAIL() << "an old result was decoded";
        } catch (const WireError& e) {
            EXPECT_EQ(std::string(e.what()), "result of wire protocol version " +
                                                 std::to_string(old) +
                                                 ", this coordinator speaks version "
                                                 "2: update the worker");
        }
    }
    v1::SampleJobResult message;
    to_proto(two_pixel_result(false), message);
    message.set_version(kWireVersion + 1);
    EXPECT_THROW(from_proto(message), WireError);
    EXPECT_THROW(decode_in_place(message), WireError);
}

// The bytes a version 1 worker sends for a 1x1 result: its arrays' reserved fields
// (samples = 2 as field 5, a varint) parse as unknown fields, and the version refuses it.
TEST(Wire, AVersionOneMessageParsesAndIsRefused) {
    const std::string v1_bytes = {
        0x0a, 0x04, 0x18, 0x01, 0x20, 0x01,  // rect 1x1 (width 3, height 4)
        0x28, 0x02,                          // samples: 2
        0x48, 0x01,                          // version: 1
    };
    v1::SampleJobResult message;
    ASSERT_TRUE(message.ParseFromString(v1_bytes));
    EXPECT_TRUE(message.pixels().empty());
    EXPECT_THROW(from_proto(message), WireError);
}

TEST(Wire, FirstHitSumsOfTheWrongLengthAreRefused) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(true), message);
    for (const size_t size : {kFirstHitRecordBytes, 2 * kFirstHitRecordBytes - 8,
                              2 * kFirstHitRecordBytes + 1, 3 * kFirstHitRecordBytes}) {
        v1::SampleJobResult wrong = message;
        wrong.mutable_first_hits()->resize(size);
        EXPECT_THROW(from_proto(wrong), WireError) << size << " bytes";
        EXPECT_THROW(decode_in_place(wrong), WireError) << size << " bytes";
    }
}

}  // namespace
}  // namespace aliquot
