// The job and result messages' mapping, and its version check (issue 34's first-hit
// sums).
#include "wire.h"

#include <gtest/gtest.h>

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

// A render that is not denoised pays nothing: no first-hit fields on the wire, so its
// results are the bytes they were but for the version's two.
TEST(Wire, AResultWithoutFirstHitSumsCarriesNone) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(false), message);
    EXPECT_EQ(message.sum_albedo_size(), 0);
    EXPECT_EQ(message.sum_normal_size(), 0);
    v1::SampleJobResult unversioned = message;
    unversioned.clear_version();
    EXPECT_EQ(message.ByteSizeLong(), unversioned.ByteSizeLong() + 2);
    EXPECT_TRUE(from_proto(message).first_hits.empty());
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

// A worker from before the first-hit sums sends no version: its result is refused whole,
// with a message that says what to do.
TEST(Wire, AResultOfAnOlderVersionIsRefusedWithAClearError) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(false), message);
    message.set_version(0);
    try {
        from_proto(message);
        FAIL() << "an old result was decoded";
    } catch (const WireError& e) {
        EXPECT_STREQ(e.what(),
                     "result of wire protocol version 0, this coordinator speaks version "
                     "1: update the worker");
    }
    message.set_version(kWireVersion + 1);
    EXPECT_THROW(from_proto(message), WireError);
}

TEST(Wire, FirstHitSumsOfTheWrongLengthAreRefused) {
    v1::SampleJobResult message;
    to_proto(two_pixel_result(true), message);
    v1::SampleJobResult short_albedo = message;
    short_albedo.mutable_sum_albedo()->RemoveLast();
    EXPECT_THROW(from_proto(short_albedo), WireError);
    v1::SampleJobResult no_normal = message;
    no_normal.clear_sum_normal();
    EXPECT_THROW(from_proto(no_normal), WireError);
}

}  // namespace
}  // namespace aliquot
