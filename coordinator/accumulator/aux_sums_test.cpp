#include "aux_sums.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "aov_channels.h"

namespace aliquot {
namespace {

// One pixel at (x, y) of n samples, each of colour 1, albedo `albedo` and normal +z.
SampleJobResult one_pixel(uint32_t x, uint32_t y, uint64_t n, double albedo) {
    SampleJobResult r;
    r.rect = {x, y, 1, 1};
    r.pixels.resize(1);
    r.pixels[0].samples = n;
    r.pixels[0].even[0] = r.pixels[0].even[1] = r.pixels[0].even[2] = double(n);
    r.first_hits.resize(1);
    for (int c = 0; c < 3; ++c) r.first_hits[0].albedo[c] = albedo * double(n);
    r.first_hits[0].normal[2] = double(n);
    return r;
}

bool same_bits(const Accumulator& a, const Accumulator& b) {
    for (size_t i = 0; i < a.pixel_count(); ++i)
        if (std::memcmp(&a.at(i), &b.at(i), sizeof(PixelSums)) != 0) return false;
    return a.total_samples() == b.total_samples();
}

TEST(AuxSums, MeansAreTheSumsOverEachPixelsSamples) {
    Accumulator merged(2, 1);
    AuxSums aux(2, 1);
    merge_with_aux(merged, aux, one_pixel(1, 0, 4, 0.5));
    merge_with_aux(merged, aux, one_pixel(1, 0, 4, 0.25));
    const Image albedo = aux.albedo(merged), normal = aux.normal(merged);
    ASSERT_EQ(albedo.pixel_count(), 2u);
    EXPECT_FLOAT_EQ(albedo.rgb[3 * 1 + 0], 0.375f);
    EXPECT_FLOAT_EQ(normal.rgb[3 * 1 + 2], 1.0f);
    for (int c = 0; c < 3; ++c) {  // no samples: 0, not NaN
        EXPECT_EQ(albedo.rgb[c], 0.0f);
        EXPECT_EQ(normal.rgb[c], 0.0f);
    }
}

TEST(AuxSums, LayersAreNamedAsAovChannelsSays) {
    Accumulator merged(1, 1);
    AuxSums aux(1, 1);
    merge_with_aux(merged, aux, one_pixel(0, 0, 2, 0.5));
    Image image = merged.image(true);
    aux.add_layers(merged, image);
    std::vector<std::string> names;
    for (const Image::Channel& c : image.extra) names.push_back(c.name);
    EXPECT_EQ(names, (std::vector<std::string>{kSampleCountChannel, kVarianceChannel,
                                               "albedo.R", "albedo.G", "albedo.B",
                                               "normal.X", "normal.Y", "normal.Z"}));
    EXPECT_FLOAT_EQ(image.extra[2].values[0], 0.5f);
    EXPECT_FLOAT_EQ(image.extra[7].values[0], 1.0f);
}

// Every refusal leaves the colour sums and the first-hit sums exactly as they were.
TEST(AuxSums, ARefusedResultLeavesBothAsTheyWere) {
    Accumulator merged(2, 1), before(2, 1);
    AuxSums aux(2, 1), aux_of_before(2, 1);
    merge_with_aux(merged, aux, one_pixel(0, 0, 2, 0.5));
    merge_with_aux(before, aux_of_before, one_pixel(0, 0, 2, 0.5));
    const FirstHitSums aux_before = aux.at(0);

    SampleJobResult nan = one_pixel(0, 0, 2, 0.5);
    nan.first_hits[0].normal[1] = std::numeric_limits<double>::quiet_NaN();
    SampleJobResult too_bright = one_pixel(0, 0, 2, 0.5);
    too_bright.first_hits[0].albedo[0] = 3.0;  // 2 samples add at most 2
    SampleJobResult none = one_pixel(0, 0, 2, 0.5);
    none.first_hits.clear();
    SampleJobResult no_samples = one_pixel(0, 0, 0, 0.0);
    no_samples.first_hits[0].albedo[1] = 0.5;
    SampleJobResult outside = one_pixel(2, 0, 2, 0.5);  // the colour's check refuses it
    for (const SampleJobResult* r : {&nan, &too_bright, &none, &no_samples, &outside}) {
        EXPECT_THROW(merge_with_aux(merged, aux, *r), MergeError);
        EXPECT_TRUE(same_bits(merged, before));
        EXPECT_EQ(aux.at(0), aux_before);
        EXPECT_EQ(aux.at(1), FirstHitSums{});
    }
}

// A render that did not ask keeps nothing and refuses sums it did not ask for.
TEST(AuxSums, ARenderThatDidNotAskKeepsNone) {
    Accumulator merged(1, 1);
    AuxSums aux;
    EXPECT_FALSE(aux.kept());
    EXPECT_THROW(merge_with_aux(merged, aux, one_pixel(0, 0, 2, 0.5)), MergeError);
    EXPECT_EQ(merged.total_samples(), 0u);
    SampleJobResult plain = one_pixel(0, 0, 2, 0.5);
    plain.first_hits.clear();
    merge_with_aux(merged, aux, plain);
    EXPECT_EQ(merged.total_samples(), 2u);
    EXPECT_EQ(aux.albedo(merged).pixel_count(), 0u);
    Image image = merged.image(true);
    aux.add_layers(merged, image);
    EXPECT_EQ(image.extra.size(), 2u);
}

}  // namespace
}  // namespace aliquot
