// A render with a reference reports each round's mean bias against it beside its E: E
// falls as a biased method converges while its image stays too dark, which only the bias
// shows. Kept in memory and in the record, read back after a restart; absent without a
// reference and for a black one (a bias relative to nothing).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <thread>

#include "farm_test_results.h"

namespace aliquot {
namespace {

namespace fs = std::filesystem;

class RoundBiasTest : public ::testing::Test {
protected:
    RoundBiasTest()
        : dir(fs::temp_directory_path() /
              ("aliquot_round_bias_test_" + std::to_string(getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
        fs::remove_all(dir);
    }
    ~RoundBiasTest() override { fs::remove_all(dir); }

    // 32x32 pixels (four 16x16 blocks: enough for a standard error), one round.
    static RenderSpec spec_with(float reference_value) {
        RenderSpec spec = small_test_spec();
        spec.width = spec.height = 32;
        spec.reference = Image(32, 32);
        std::fill(spec.reference->rgb.begin(), spec.reference->rgb.end(),
                  reference_value);
        return spec;
    }
    // Every pixel 0.475: 5 % darker than a reference of 0.5.
    static void render_dark(Coordinator& c) {
        const std::string session = c.register_worker("dark", 1).session;
        while (const std::optional<LeaseGrant> grant =
                   c.lease(session, std::chrono::milliseconds(0))) {
            SampleJobResult result = zero_result(*grant);
            for (PixelSums& p : result.pixels)
                for (int ch = 0; ch < 3; ++ch)
                    p.even[ch] = p.odd[ch] = 0.2375 * double(p.samples);
            c.complete(session, grant->lease_id, result);
        }
    }
    static bool wait_for_sessions(Coordinator& c, size_t n) {
        for (int i = 0; i < 500 && c.sessions_in_memory() != n; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        return c.sessions_in_memory() == n;
    }

    fs::path dir;
};

TEST_F(RoundBiasTest, ARoundOfARenderWithAReferenceReportsItsBiasInMemoryAndOnRecord) {
    CoordinatorOptions options;
    options.data_dir = dir;
    std::string id;
    {
        Coordinator c(options);
        id = c.submit(spec_with(0.5f));
        render_dark(c);
        ASSERT_EQ(c.info(id)->state, RenderState::Done);
        for (const bool from_record : {false, true}) {
            SCOPED_TRACE(from_record ? "from the record" : "in memory");
            if (from_record) ASSERT_TRUE(wait_for_sessions(c, 0));
            const std::optional<RenderInfo> info = c.info(id);
            ASSERT_TRUE(info->mean_bias && info->mean_bias_se);
            EXPECT_NEAR(*info->mean_bias, -0.05, 1e-6);
            EXPECT_NEAR(*info->mean_bias_se, 0, 1e-9);  // every block alike
            const auto rounds = c.rounds(id);
            ASSERT_TRUE(rounds && !rounds->empty());
            EXPECT_NEAR(rounds->back().mean_bias.value_or(0), -0.05, 1e-6);
            EXPECT_TRUE(rounds->back().mean_bias_se.has_value());
        }
    }
    Coordinator restarted(options);
    EXPECT_NEAR(restarted.info(id)->mean_bias.value_or(0), -0.05, 1e-6);
    EXPECT_NEAR(restarted.rounds(id)->back().mean_bias.value_or(0), -0.05, 1e-6);
}

TEST_F(RoundBiasTest, NoReferenceOrABlackOneHasNoBias) {
    Coordinator c(CoordinatorOptions{});  // in memory: its rounds and info stay there
    const std::string black = c.submit(spec_with(0.0f));
    const std::string none = c.submit(small_test_spec());
    render_dark(c);
    for (const std::string& id : {black, none}) {
        SCOPED_TRACE(id);
        ASSERT_EQ(c.info(id)->state, RenderState::Done);
        EXPECT_FALSE(c.info(id)->mean_bias);
        EXPECT_FALSE(c.info(id)->mean_bias_se);
        ASSERT_FALSE(c.rounds(id)->empty());
        EXPECT_FALSE(c.rounds(id)->back().mean_bias);
    }
    EXPECT_GT(c.info(black)->error_vs_reference, 0);  // E is there; the bias is not
}

}  // namespace
}  // namespace aliquot
