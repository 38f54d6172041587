// A round's mean bias against the reference: kept beside its E, absent where it was not
// measured, and a database from before migration 8 loads with its rounds unbiased.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "store.h"

namespace aliquot {
namespace {

namespace fs = std::filesystem;

class RoundsBiasStoreTest : public testing::Test {
protected:
    void SetUp() override {
        dir = fs::temp_directory_path() /
              ("aliquot_rounds_bias_" + std::to_string(getpid()) + "_" +
               testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir);
    }
    void TearDown() override { fs::remove_all(dir); }

    static void seed(RunStore& store) {
        store.put_scene("h1", "cornell-box", "{}", 1);
        RenderRecord r;
        r.id = "r-1";
        r.scene_hash = "h1";
        r.spec_json = "{}";
        r.created_at = 10;
        store.create_render(r);
    }
    static RoundRecord round_of(int64_t idx) {
        RoundRecord r;
        r.render_id = "r-1";
        r.idx = idx;
        r.samples_in_round = 100;
        r.samples_total = 100 * (idx + 1);
        r.seconds = 1;
        r.error_estimate = 0.5;
        r.created_at = 1000 + idx;
        return r;
    }
    // Runs `sql` on the database file, outside the store.
    void raw(const std::string& sql) {
        sqlite3* db = nullptr;
        ASSERT_EQ(sqlite3_open((dir / "aliquot.db").c_str(), &db), SQLITE_OK);
        char* error = nullptr;
        const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error);
        EXPECT_EQ(rc, SQLITE_OK) << (error ? error : "");
        sqlite3_free(error);
        sqlite3_close(db);
    }

    fs::path dir;
};

TEST_F(RoundsBiasStoreTest, ARoundKeepsItsBiasAndAnUnmeasuredOneHasNone) {
    RunStore store(dir);
    seed(store);
    RoundRecord biased = round_of(1);
    biased.error_vs_reference = 0.125;
    biased.mean_bias = -0.05;
    biased.mean_bias_se = 0.002;
    EXPECT_TRUE(store.add_round(round_of(0)));
    EXPECT_TRUE(store.add_round(biased));
    const auto rounds = store.rounds("r-1");
    ASSERT_EQ(rounds.size(), 2u);
    EXPECT_FALSE(rounds[0].mean_bias);
    EXPECT_FALSE(rounds[0].mean_bias_se);
    EXPECT_EQ(rounds[1].mean_bias, -0.05);
    EXPECT_EQ(rounds[1].mean_bias_se, 0.002);
    EXPECT_EQ(store.last_round("r-1")->mean_bias, -0.05);

    // SQLite would keep NaN as NULL, which reads back as "not measured": refused.
    RoundRecord nan = round_of(2);
    nan.mean_bias = std::nan("");
    EXPECT_THROW(store.add_round(nan), StoreError);
    RoundRecord inf = round_of(2);
    inf.mean_bias = 0;
    inf.mean_bias_se = INFINITY;
    EXPECT_THROW(store.add_round(inf), StoreError);
}

TEST_F(RoundsBiasStoreTest, ADatabaseFromBeforeTheRoundsBiasLoadsWithItsRoundsUnbiased) {
    {
        RunStore store(dir);
        seed(store);
    }
    raw("DELETE FROM schema_migrations WHERE version = 8;"
        "ALTER TABLE rounds DROP COLUMN mean_bias;"
        "ALTER TABLE rounds DROP COLUMN mean_bias_se;"
        "INSERT INTO rounds (render_id, idx, samples_in_round, samples_total, seconds,"
        " error_estimate, error_vs_reference, created_at)"
        " VALUES ('r-1', 0, 100, 100, 1.0, 0.5, 0.25, 1000)");
    RunStore store(dir);
    EXPECT_EQ(store.schema_version(), RunStore::latest_schema_version());
    const auto old = store.rounds("r-1");
    ASSERT_EQ(old.size(), 1u);
    EXPECT_EQ(old[0].error_vs_reference, 0.25);
    EXPECT_FALSE(old[0].mean_bias);
    EXPECT_FALSE(old[0].mean_bias_se);
    RoundRecord fresh = round_of(1);
    fresh.mean_bias = 0.01;
    fresh.mean_bias_se = 0.004;
    EXPECT_TRUE(store.add_round(fresh));
    EXPECT_EQ(store.rounds("r-1").at(1).mean_bias, 0.01);
}

}  // namespace
}  // namespace aliquot
