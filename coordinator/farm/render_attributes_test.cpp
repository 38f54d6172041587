#include "render_attributes.h"

#include <gtest/gtest.h>

namespace aliquot {

TEST(RenderAttributes, NameTheSpecThatFixesThePixels) {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.seed = UINT64_MAX;
    spec.strategy.method = "uniform";
    spec.strategy.spp = 4;
    const auto a = render_attributes(spec, "abc123", 400, 100);
    EXPECT_EQ(a.at("aliquot:sceneHash"), "abc123");
    EXPECT_EQ(a.at("aliquot:method"), "uniform");
    EXPECT_EQ(a.at("aliquot:seed"), "18446744073709551615");
    EXPECT_EQ(a.at("aliquot:budget"), "400");
    EXPECT_EQ(a.at("aliquot:samples"), "100");
    EXPECT_EQ(nlohmann::json::parse(a.at("aliquot:strategy"))["spp"], 4);
}

TEST(RenderAttributes, LeaveOutWhatDoesNotChangeThePixels) {
    RenderSpec a, b;
    a.scene_name = "scenes/box.json";
    b.scene_name = "../elsewhere/box.json";
    b.reference = Image(1, 1);
    EXPECT_EQ(render_attributes(a, "h", 1, 1), render_attributes(b, "h", 1, 1));
}

}  // namespace aliquot
