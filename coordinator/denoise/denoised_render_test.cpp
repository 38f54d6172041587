#include "denoised_render.h"

#include <gtest/gtest.h>

#include "aov_channels.h"
#include "test_denoiser.h"

namespace aliquot {
namespace {

Image grey_render(uint32_t size, float level) {
    Image image(size, size);
    for (size_t i = 0; i < image.rgb.size(); ++i)
        image.rgb[i] = level * (0.5f + float((i * 7919) % 101) / 100.0f);
    return image;
}

void add_layer(Image& image, const char* const (&names)[3], float value) {
    for (const char* name : names)
        image.extra.push_back({name, std::vector<float>(image.pixel_count(), value)});
}

TEST(DenoisedRender, UsesTheRendersAlbedoAndNormalLayers) {
    REQUIRE_DENOISER(denoiser);
    Image render = grey_render(16, 0.5f);
    std::string error;
    bool used_aux = true;
    ASSERT_TRUE(denoise_render(*denoiser, render, &error, &used_aux)) << error;
    EXPECT_FALSE(used_aux);
    add_layer(render, kAlbedoChannels, 0.7f);
    add_layer(render, kNormalChannels, 0.5f);
    const std::optional<Image> denoised =
        denoise_render(*denoiser, render, &error, &used_aux);
    ASSERT_TRUE(denoised) << error;
    EXPECT_TRUE(used_aux);
    EXPECT_EQ(denoised->pixel_count(), render.pixel_count());
    EXPECT_TRUE(denoised->extra.empty());
}

TEST(DenoisedRender, LayerReadsBackAndReplacesTheOldOne) {
    Image render = grey_render(4, 1.0f);
    EXPECT_FALSE(denoised_layer(render));
    Image first = grey_render(4, 2.0f);
    add_denoised_layer(first, false, render);
    Image second = grey_render(4, 3.0f);
    add_denoised_layer(second, true, render);
    EXPECT_EQ(render.extra.size(), 3u);
    const std::optional<Image> back = denoised_layer(render);
    ASSERT_TRUE(back);
    EXPECT_EQ(back->rgb, second.rgb);
    EXPECT_NE(render.attributes.at("aliquot:denoised").find("albedo and normal"),
              std::string::npos);
}

}  // namespace
}  // namespace aliquot
