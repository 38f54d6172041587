// A submission's "albedo_normal" (SubmitRequest.albedo_normal): the render traces first
// hits for a denoiser (RenderSpec::aux, issue 34).
#include <gtest/gtest.h>

#include "http_api.h"

namespace aliquot::http_api {
namespace {

TEST(AlbedoNormalRequest, AsksForFirstHitsOnlyWhenTrue) {
    EXPECT_FALSE(parse_render_request(R"({"scene": "cornell-box"})").aux);
    EXPECT_TRUE(parse_render_request(R"({"albedo_normal": true})").aux);
    EXPECT_FALSE(parse_render_request(R"({"albedo_normal": false})").aux);
}

TEST(AlbedoNormalRequest, AnythingButABooleanIsRefused) {
    EXPECT_THROW(parse_render_request(R"({"albedo_normal": 1})"), ApiError);
    EXPECT_THROW(parse_render_request(R"({"albedo_normal": "yes"})"), ApiError);
}

}  // namespace
}  // namespace aliquot::http_api
