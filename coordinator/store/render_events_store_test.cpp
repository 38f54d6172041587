// The store's side of a render's events: numbered per render, the middle of a long
// render dropped, gone with the render.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "store.h"

namespace aliquot {
namespace {

namespace fs = std::filesystem;

class RenderEventsStoreTest : public testing::Test {
protected:
    void SetUp() override {
        dir = fs::temp_directory_path() /
              ("aliquot_events_" + std::to_string(getpid()) + "_" +
               testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir);
        store = std::make_unique<RunStore>(dir);
        store->put_scene("h1", "cornell-box", "{}", 1);
        RenderRecord r;
        r.id = "r-1";
        r.scene_hash = "h1";
        r.spec_json = "{}";
        r.created_at = 10;
        store->create_render(r);
    }
    void TearDown() override {
        store.reset();
        fs::remove_all(dir);
    }
    void add(int64_t seq) {
        store->add_render_event({"r-1", seq, 100 + seq, "round_ended", "{\"round\":1}"},
                                4, 6);
    }

    fs::path dir;
    std::unique_ptr<RunStore> store;
};

TEST_F(RenderEventsStoreTest, AFloodOfRoundsKeepsTheFirstAndLastOnly) {
    for (int64_t seq = 0; seq < 10000; ++seq) add(seq);
    const auto [count, last] = store->render_event_span("r-1");
    EXPECT_EQ(count, 10);
    EXPECT_EQ(last, 9999);
    const std::vector<RenderEventRecord> kept = store->render_events("r-1", -1, 100);
    ASSERT_EQ(kept.size(), 10u);
    EXPECT_EQ(kept[3].seq, 3);
    EXPECT_EQ(kept[4].seq, 9994);
    EXPECT_EQ(kept[9].seq, 9999);
    EXPECT_EQ(kept[9].kind, "round_ended");
    EXPECT_EQ(kept[9].fields_json, "{\"round\":1}");
}

TEST_F(RenderEventsStoreTest, ReadsAfterASeqAndRecordingAgainIsANoOp) {
    for (int64_t seq = 0; seq < 3; ++seq) add(seq);
    add(1);
    EXPECT_EQ(store->render_event_span("r-1").first, 3);
    const std::vector<RenderEventRecord> after = store->render_events("r-1", 0, 1);
    ASSERT_EQ(after.size(), 1u);
    EXPECT_EQ(after[0].seq, 1);
}

TEST_F(RenderEventsStoreTest, AnUnknownRenderHasNoneAndTakesNone) {
    EXPECT_TRUE(store->render_events("r-404", -1, 10).empty());
    EXPECT_EQ(store->render_event_span("r-404").second, -1);
    EXPECT_THROW(store->add_render_event({"r-404", 0, 1, "submitted", "{}"}, 4, 6),
                 StoreError);  // foreign key
}

TEST_F(RenderEventsStoreTest, EventsGoWithTheirRender) {
    add(0);
    store->finish_render("r-1", RenderState::Done, "{}", 200);
    ASSERT_TRUE(store->delete_render("r-1", 300));
    EXPECT_EQ(store->render_event_span("r-1").first, 0);
}

}  // namespace
}  // namespace aliquot
