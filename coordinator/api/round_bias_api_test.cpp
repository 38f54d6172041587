// A render with a reference serves each round's mean bias against it beside its E, over
// gRPC (optional fields, absent when there is none) and HTTP (null then, never a JSON
// NaN): a method converging to an image 5 % too dark shows it while E falls.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <chrono>

#include "aliquot.grpc.pb.h"
#include "exr_io.h"
#include "grpc_server.h"
#include "http_api.h"
#include "http_server.h"
#include "scene_loader.h"
#include "test_tokens.h"

namespace aliquot {
namespace {

using nlohmann::json;

// side x side, one round; every pixel of the reference `value`.
Image flat(uint32_t side, float value) {
    Image image(side, side);
    std::fill(image.rgb.begin(), image.rgb.end(), value);
    return image;
}

// Every pixel 0.475: 5 % darker than a reference of 0.5.
void render_dark(Coordinator& c) {
    const std::string session = c.register_worker("dark", 1).session;
    while (const std::optional<LeaseGrant> grant =
               c.lease(session, std::chrono::milliseconds(0))) {
        SampleJobResult result;
        result.rect = grant->job.rect;
        result.pixels.resize(grant->job.counts.size());
        for (size_t i = 0; i < result.pixels.size(); ++i) {
            PixelSums& p = result.pixels[i];
            p.samples = grant->job.counts[i];
            for (int ch = 0; ch < 3; ++ch)
                p.even[ch] = p.odd[ch] = 0.2375 * double(p.samples);
        }
        c.complete(session, grant->lease_id, result);
    }
}

TEST(RoundBiasOverGrpc, RoundsAndTheRenderCarryTheBiasAndABlackReferenceNone) {
    Coordinator coordinator(CoordinatorOptions{});
    GrpcServer server(coordinator, "127.0.0.1:0", testing::test_security());
    auto stub = v1::ClientService::NewStub(testing::loopback_channel(server.port()));
    std::string ids[2];
    for (int black = 0; black < 2; ++black) {
        testing::TokenContext ctx(Role::Client);
        v1::SubmitRequest req =
            testing::small_submission(self_contained_scene_json("cornell-box"), 32);
        req.set_reference_exr(encode_exr(flat(32, black ? 0.0f : 0.5f)));
        v1::RenderInfo reply;
        ASSERT_TRUE(stub->Submit(&ctx, req, &reply).ok());
        EXPECT_FALSE(reply.has_mean_bias());  // no round yet
        ids[black] = reply.id();
    }
    render_dark(coordinator);
    for (int black = 0; black < 2; ++black) {
        SCOPED_TRACE(black ? "black reference" : "reference of 0.5");
        v1::GetRenderRequest req;
        req.set_id(ids[black]);
        v1::GetRoundsReply rounds;
        v1::RenderInfo info;
        {
            testing::TokenContext ctx(Role::Client);
            ASSERT_TRUE(stub->GetRounds(&ctx, req, &rounds).ok());
        }
        {
            testing::TokenContext ctx(Role::Client);
            ASSERT_TRUE(stub->GetRender(&ctx, req, &info).ok());
        }
        ASSERT_GT(rounds.rounds_size(), 0);
        const v1::RoundInfo& last = rounds.rounds(rounds.rounds_size() - 1);
        EXPECT_EQ(last.has_mean_bias(), !black);
        EXPECT_EQ(last.has_mean_bias_se(), !black);
        EXPECT_EQ(info.has_mean_bias(), !black);
        EXPECT_GT(info.error_vs_reference(), 0);
        if (black) continue;
        EXPECT_NEAR(last.mean_bias(), -0.05, 1e-6);
        EXPECT_NEAR(info.mean_bias(), -0.05, 1e-6);
        EXPECT_NEAR(info.mean_bias_se(), 0, 1e-9);  // every 16x16 block alike
    }
}

TEST(RoundBiasOverHttp, RoundRowsAndTheRenderCarryTheBiasAndABlackReferenceNull) {
    Coordinator coordinator(CoordinatorOptions{});
    HttpOptions options;
    options.tokens = testing::kTestTokens;
    HttpServer server(coordinator, "127.0.0.1:0", options);
    httplib::Client client("127.0.0.1", server.port());
    client.set_read_timeout(10, 0);
    client.set_bearer_token_auth(testing::kTestTokens.client);
    std::string ids[2];
    for (int black = 0; black < 2; ++black) {
        RenderSpec spec;
        spec.scene_name = "cornell-box";
        spec.scene_json = self_contained_scene_json("cornell-box");
        spec.width = spec.height = 32;
        spec.strategy.method = "uniform";
        spec.strategy.spp = 1;
        spec.reference = flat(32, black ? 0.0f : 0.5f);
        ids[black] = coordinator.submit(spec);
    }
    render_dark(coordinator);
    for (int black = 0; black < 2; ++black) {
        SCOPED_TRACE(black ? "black reference" : "reference of 0.5");
        const auto render = client.Get(("/api/renders/" + ids[black]).c_str());
        const auto rounds =
            client.Get(("/api/renders/" + ids[black] + "/rounds").c_str());
        ASSERT_TRUE(render && rounds);
        ASSERT_EQ(render->status, 200) << render->body;
        ASSERT_EQ(rounds->status, 200) << rounds->body;
        EXPECT_EQ(render->body.find("NaN"), std::string::npos) << render->body;
        EXPECT_EQ(rounds->body.find("NaN"), std::string::npos) << rounds->body;
        const json r = json::parse(render->body);
        const json table = json::parse(rounds->body);
        ASSERT_EQ(table["columns"][6], "mean_bias");
        ASSERT_EQ(table["columns"][7], "mean_bias_se");
        const json& row = table["rows"].back();
        if (black) {
            EXPECT_TRUE(r["mean_bias"].is_null());
            EXPECT_TRUE(r["mean_bias_se"].is_null());
            EXPECT_TRUE(row[6].is_null());
            EXPECT_TRUE(r["error_vs_reference"].is_number());
            continue;
        }
        EXPECT_NEAR(r["mean_bias"].get<double>(), -0.05, 1e-6);
        EXPECT_NEAR(r["mean_bias_se"].get<double>(), 0, 1e-9);
        EXPECT_NEAR(row[6].get<double>(), -0.05, 1e-6);
        EXPECT_TRUE(row[7].is_number());
    }
}

// A bias is signed, unlike E: a negative one is a measure, not "not measured"; NaN or
// none is null.
TEST(RoundBiasJson, ANegativeBiasIsKeptAndNaNOrNoneIsNull) {
    RoundSummary round;
    round.error_vs_reference = 0.1;
    round.mean_bias = -0.0168;
    round.mean_bias_se = 0.0004;
    EXPECT_EQ(http_api::round_json(round)["mean_bias"], -0.0168);
    EXPECT_EQ(http_api::round_json(round)["mean_bias_se"], 0.0004);
    round.mean_bias = std::nan("");
    round.mean_bias_se.reset();
    const json j = http_api::round_json(round);
    EXPECT_TRUE(j["mean_bias"].is_null());
    EXPECT_TRUE(j["mean_bias_se"].is_null());
    EXPECT_EQ(j.dump().find("NaN"), std::string::npos);
}

}  // namespace
}  // namespace aliquot
