#include "aov_layer.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "aov_channels.h"
#include "exr_io.h"

namespace aliquot {
namespace {

// A 2x1 image with the albedo and normal layers, pixel i's channel c worth i + c / 10.
Image with_first_hit_layers() {
    Image image(2, 1);
    for (const auto* names : {&kAlbedoChannels, &kNormalChannels})
        for (int c = 0; c < 3; ++c)
            image.extra.push_back(
                {(*names)[c], {0.1f * float(c), 1.0f + 0.1f * float(c)}});
    return image;
}

// Written to an EXR and read back, the layers come back under their names, and as
// images of their own.
TEST(AovLayer, AlbedoAndNormalLayersComeBackFromAnExr) {
    const auto path = std::filesystem::temp_directory_path() /
                      ("aliquot-aov-layer-" + std::to_string(getpid()) + ".exr");
    write_exr(path, with_first_hit_layers());
    const Image back = read_exr(path);
    std::filesystem::remove(path);
    for (const auto* names : {&kAlbedoChannels, &kNormalChannels}) {
        const std::optional<Image> layer = layer_image(back, *names);
        ASSERT_TRUE(layer);
        ASSERT_EQ(layer->pixel_count(), 2u);
        for (int c = 0; c < 3; ++c) {
            EXPECT_FLOAT_EQ(layer->rgb[c], 0.1f * float(c));
            EXPECT_FLOAT_EQ(layer->rgb[3 + c], 1.0f + 0.1f * float(c));
        }
    }
}

TEST(AovLayer, ALayerWithAChannelMissingIsNone) {
    Image image = with_first_hit_layers();
    image.extra.erase(image.extra.begin() + 1);  // albedo.G
    EXPECT_FALSE(layer_image(image, kAlbedoChannels));
    EXPECT_TRUE(layer_image(image, kNormalChannels));
}

}  // namespace
}  // namespace aliquot
