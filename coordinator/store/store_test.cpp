// RunStore against real database files in a fresh directory per test. The raw SQLite
// connection below only inspects or damages the file from outside, as another process
// would.
#include "store.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

namespace aliquot {
namespace {

namespace fs = std::filesystem;

class RunStoreTest : public testing::Test {
protected:
    void SetUp() override {
        dir = fs::temp_directory_path() /
              ("aliquot_store_" + std::to_string(getpid()) + "_" +
               testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir);
        fs::create_directories(dir);
    }
    void TearDown() override { fs::remove_all(dir); }

    fs::path db() const { return dir / "aliquot.db"; }
    fs::path wal() const { return dir / "aliquot.db-wal"; }

    fs::path dir;
};

// Runs `sql` on a separate connection and returns the first column of the first row.
std::string raw_query(const fs::path& path, const std::string& sql) {
    sqlite3* db = nullptr;
    if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) {
        sqlite3_close(db);
        ADD_FAILURE() << "cannot open " << path;
        return {};
    }
    std::string first;
    char* error = nullptr;
    const auto keep_first = [](void* out, int, char** values, char**) {
        auto* s = static_cast<std::string*>(out);
        if (s->empty() && values[0]) *s = values[0];
        return 0;
    };
    if (sqlite3_exec(db, sql.c_str(), keep_first, &first, &error) != SQLITE_OK) {
        ADD_FAILURE() << sql << ": " << (error ? error : "?");
        sqlite3_free(error);
    }
    sqlite3_close(db);
    return first;
}

RenderRecord render(const std::string& id, int64_t created_at,
                    RenderState state = RenderState::Queued) {
    RenderRecord r;
    r.id = id;
    r.scene_hash = "h1";
    r.spec_json = R"({"method":"uniform","spp":4})";
    r.state = state;
    r.created_at = created_at;
    r.samples_planned = 1000;
    return r;
}

RoundRecord round_of(const std::string& render_id, int64_t idx) {
    RoundRecord r;
    r.render_id = render_id;
    r.idx = idx;
    r.samples_in_round = 100;
    r.samples_total = 100 * (idx + 1);
    r.seconds = 0.5 * double(idx + 1);
    r.error_estimate = 1.0 / double(idx + 1);
    r.created_at = 1000 + idx;
    return r;
}

// A store with scene h1 and render r-1.
void seed(RunStore& store) {
    store.put_scene("h1", "cornell-box", R"({"type":"scene"})", 1);
    store.create_render(render("r-1", 10));
}

TEST_F(RunStoreTest, MigrationsApplyOnceAndReopeningIsIdempotent) {
    {
        RunStore store(dir);
        EXPECT_EQ(store.schema_version(), RunStore::latest_schema_version());
        seed(store);
    }
    for (int i = 0; i < 3; ++i) {
        RunStore store(dir);
        EXPECT_EQ(store.schema_version(), RunStore::latest_schema_version());
        EXPECT_TRUE(store.get_render("r-1"));
    }
    EXPECT_EQ(raw_query(db(), "SELECT COUNT(*) FROM schema_migrations"),
              std::to_string(RunStore::latest_schema_version()));
    EXPECT_EQ(raw_query(db(), "SELECT COUNT(DISTINCT version) FROM schema_migrations"),
              std::to_string(RunStore::latest_schema_version()));
}

TEST_F(RunStoreTest, CreatesTheDataDirectory) {
    RunStore store(dir / "nested" / "data");
    EXPECT_TRUE(fs::exists(dir / "nested" / "data" / "aliquot.db"));
}

TEST_F(RunStoreTest, UsesWriteAheadLog) {
    RunStore store(dir);
    seed(store);
    // The journal mode is a property of the file, seen by any other connection.
    EXPECT_EQ(raw_query(db(), "PRAGMA journal_mode"), "wal");
    EXPECT_TRUE(fs::exists(wal()));
}

TEST_F(RunStoreTest, EnforcesForeignKeys) {
    RunStore store(dir);
    seed(store);
    try {
        store.add_round(round_of("r-nope", 3));
        FAIL() << "a round of an unknown render was accepted";
    } catch (const StoreError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot add round 3 of render r-nope"),
                  std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("FOREIGN KEY"), std::string::npos)
            << e.what();
        EXPECT_EQ(e.sqlite_code() & 0xff, SQLITE_CONSTRAINT);
    }
    EXPECT_THROW(store.create_render([] {
        RenderRecord r = render("r-2", 11);
        r.scene_hash = "no-such-scene";
        return r;
    }()),
                 StoreError);
    EXPECT_TRUE(store.rounds("r-nope").empty());
    EXPECT_FALSE(store.get_render("r-2"));
}

TEST_F(RunStoreTest, RecordingARoundAgainIsANoOp) {
    RunStore store(dir);
    seed(store);
    EXPECT_TRUE(store.add_round(round_of("r-1", 0)));
    // A restarted coordinator re-records it later: other wall time, same samples.
    RoundRecord again = round_of("r-1", 0);
    again.seconds = 99;
    again.created_at = 5000;
    EXPECT_FALSE(store.add_round(again));
    EXPECT_FALSE(store.add_round(round_of("r-1", 0)));

    const auto rounds = store.rounds("r-1");
    ASSERT_EQ(rounds.size(), 1u);
    EXPECT_EQ(rounds[0].seconds, 0.5);
    EXPECT_EQ(rounds[0].created_at, 1000);

    RoundRecord different = round_of("r-1", 0);
    different.samples_in_round = 7;
    EXPECT_THROW(store.add_round(different), StoreError);
    EXPECT_EQ(store.rounds("r-1").size(), 1u);
}

TEST_F(RunStoreTest, RecordingARoundRecordsTheRendersProgress) {
    RunStore store(dir);
    seed(store);
    RoundRecord r = round_of("r-1", 0);
    r.samples_total = 12345;
    store.add_round(r);
    EXPECT_EQ(store.get_render("r-1")->samples_done, 12345);
}

TEST_F(RunStoreTest, RoundsRoundTripInOrder) {
    RunStore store(dir);
    seed(store);
    RoundRecord last = round_of("r-1", 2);
    last.error_vs_reference = 0.125;
    last.buckets_json = R"([{"x":0,"y":0,"w":16,"h":16}])";
    EXPECT_TRUE(store.add_round(last));
    EXPECT_TRUE(store.add_round(round_of("r-1", 0)));
    EXPECT_TRUE(store.add_round(round_of("r-1", 1)));

    const auto rounds = store.rounds("r-1");
    ASSERT_EQ(rounds.size(), 3u);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(rounds[i].idx, i);
    EXPECT_FALSE(rounds[0].error_vs_reference);
    EXPECT_TRUE(rounds[0].buckets_json.empty());
    EXPECT_EQ(rounds[2].error_vs_reference, 0.125);
    EXPECT_EQ(rounds[2].buckets_json, last.buckets_json);
    EXPECT_EQ(rounds[2].samples_total, 300);
    EXPECT_EQ(rounds[2].error_estimate, 1.0 / 3.0);

    RoundRecord nan = round_of("r-1", 3);
    nan.error_estimate = std::nan("");
    EXPECT_THROW(store.add_round(nan), StoreError);
}

TEST_F(RunStoreTest, LastRoundIsTheHighestNumberedWhateverTheInsertionOrder) {
    RunStore store(dir);
    seed(store);
    EXPECT_FALSE(store.last_round("r-1"));
    RoundRecord last = round_of("r-1", 2);
    last.error_vs_reference = 0.125;
    EXPECT_TRUE(store.add_round(last));
    EXPECT_TRUE(store.add_round(round_of("r-1", 0)));
    const auto got = store.last_round("r-1");
    ASSERT_TRUE(got);
    EXPECT_EQ(got->idx, 2);
    EXPECT_EQ(got->error_vs_reference, 0.125);
    EXPECT_EQ(got->samples_total, last.samples_total);
}

TEST_F(RunStoreTest, ListsRendersNewestFirstAndFiltersByState) {
    RunStore store(dir);
    store.put_scene("h1", "cornell-box", "{}", 1);
    store.create_render(render("a", 100));
    store.create_render(render("b", 300, RenderState::Running));
    store.create_render(render("c", 200));
    store.create_render(render("d", 300));  // same time as b, inserted later: newer

    const auto ids = [](const std::vector<RenderRecord>& renders) {
        std::vector<std::string> out;
        for (const auto& r : renders) out.push_back(r.id);
        return out;
    };
    EXPECT_EQ(ids(store.list_renders(0)), (std::vector<std::string>{"d", "b", "c", "a"}));
    EXPECT_EQ(ids(store.list_renders(2)), (std::vector<std::string>{"d", "b"}));
    EXPECT_EQ(ids(store.list_renders(0, RenderState::Queued)),
              (std::vector<std::string>{"d", "c", "a"}));
    EXPECT_EQ(ids(store.list_renders(1, RenderState::Queued)),
              (std::vector<std::string>{"d"}));
    EXPECT_EQ(ids(store.list_renders(0, RenderState::Running)),
              (std::vector<std::string>{"b"}));
    EXPECT_TRUE(store.list_renders(0, RenderState::Done).empty());
}

TEST_F(RunStoreTest, CountsRendersByState) {
    RunStore store(dir);
    store.put_scene("h1", "cornell-box", "{}", 1);
    EXPECT_TRUE(store.count_renders_by_state().empty());
    store.create_render(render("a", 100));
    store.create_render(render("b", 300, RenderState::Running));
    store.create_render(render("c", 200));
    store.finish_render("c", RenderState::Failed, "{}", 400);
    const std::map<RenderState, uint64_t> want = {
        {RenderState::Queued, 1}, {RenderState::Running, 1}, {RenderState::Failed, 1}};
    EXPECT_EQ(store.count_renders_by_state(), want);
}

// The TSan run of issue 33's review: a render's start is noted after its lock is let go,
// so a cancel in that gap records its end first; the late "running" must not undo it, or
// a restart would resume a render its client cancelled.
TEST_F(RunStoreTest, ALateRunningNeverUndoesAnEnd) {
    RunStore store(dir);
    seed(store);
    store.update_render_state("r-1", RenderState::Cancelled, "", 20);
    store.update_render_state("r-1", RenderState::Running, "", 30);
    const auto r = store.get_render("r-1");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->state, RenderState::Cancelled);
    EXPECT_EQ(r->finished_at, 20);
    EXPECT_FALSE(r->started_at);
    EXPECT_THROW(store.update_render_state("r-x", RenderState::Running, "", 40),
                 StoreError);
}

TEST_F(RunStoreTest, RenderLifecycleStampsTimes) {
    RunStore store(dir);
    seed(store);
    store.update_render_state("r-1", RenderState::Running, "", 20);
    store.update_render_progress("r-1", 400, R"({"round":4})");
    store.update_render_state("r-1", RenderState::Queued, "", 25);  // coordinator restart
    store.update_render_state("r-1", RenderState::Running, "",
                              30);  // keeps the first start
    store.finish_render("r-1", RenderState::Done, R"({"mean_abs":0.01})", 40);

    const auto r = store.get_render("r-1");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->state, RenderState::Done);
    EXPECT_EQ(r->created_at, 10);
    EXPECT_EQ(r->started_at, 20);
    EXPECT_EQ(r->finished_at, 40);
    EXPECT_EQ(r->samples_planned, 1000);
    EXPECT_EQ(r->samples_done, 400);
    EXPECT_EQ(r->strategy_state_json, R"({"round":4})");
    EXPECT_EQ(r->outcome_json, R"({"mean_abs":0.01})");
    EXPECT_TRUE(r->error.empty());
    EXPECT_EQ(r->spec_json, R"({"method":"uniform","spp":4})");

    EXPECT_THROW(store.finish_render("r-1", RenderState::Running, "{}", 50), StoreError);
    EXPECT_THROW(store.update_render_state("r-x", RenderState::Running, "", 50),
                 StoreError);
    EXPECT_THROW(store.update_render_progress("r-x", 1, ""), StoreError);
    EXPECT_THROW(store.create_render(render("r-1", 60)), StoreError);  // id taken
    EXPECT_FALSE(store.get_render("r-x"));

    store.create_render(render("r-2", 70));
    store.update_render_state("r-2", RenderState::Failed, "scene.json: /shapes/0: bad",
                              80);
    const auto failed = store.get_render("r-2");
    EXPECT_EQ(failed->error, "scene.json: /shapes/0: bad");
    EXPECT_EQ(failed->finished_at, 80);
    EXPECT_FALSE(failed->started_at);
}

TEST_F(RunStoreTest, UnfinishedRendersAreQueuedAndRunningOldestFirst) {
    RunStore store(dir);
    store.put_scene("h1", "cornell-box", "{}", 1);
    store.create_render(render("done", 1, RenderState::Done));
    store.create_render(render("running", 3, RenderState::Running));
    store.create_render(render("queued", 2));
    store.create_render(render("cancelled", 4, RenderState::Cancelled));
    const auto unfinished = store.unfinished_renders();
    ASSERT_EQ(unfinished.size(), 2u);
    EXPECT_EQ(unfinished[0].id, "queued");
    EXPECT_EQ(unfinished[1].id, "running");
}

TEST_F(RunStoreTest, ScenesAreStoredOnceByHash) {
    RunStore store(dir);
    EXPECT_TRUE(store.put_scene("h1", "cornell-box", "{}", 5));
    EXPECT_FALSE(store.put_scene("h1", "another name", "{}", 6));
    const auto scene = store.get_scene("h1");
    ASSERT_TRUE(scene);
    EXPECT_EQ(scene->name, "cornell-box");
    EXPECT_EQ(scene->json, "{}");
    EXPECT_EQ(scene->created_at, 5);
    EXPECT_FALSE(store.get_scene("h2"));
    EXPECT_THROW(store.put_scene("h1", "cornell-box", R"({"x":1})", 7), StoreError);
}

TEST_F(RunStoreTest, WorkersAccumulateSamplesAndKeepTheirState) {
    RunStore store(dir);
    store.upsert_worker("w1", 8, 100);
    store.record_worker_samples("w1", 500, 110);
    store.record_worker_samples("w1", 250, 105);  // late report: last_seen stays 110
    store.mark_worker_state("w1", "lost");
    store.upsert_worker("b0", 2, 120);

    auto workers = store.workers();
    ASSERT_EQ(workers.size(), 2u);
    EXPECT_EQ(workers[0].name, "b0");
    const WorkerRecord& w1 = workers[1];
    EXPECT_EQ(w1.threads, 8);
    EXPECT_EQ(w1.first_seen, 100);
    EXPECT_EQ(w1.last_seen, 110);
    EXPECT_EQ(w1.samples_traced, 750);
    EXPECT_EQ(w1.state, "lost");

    store.upsert_worker("w1", 16, 200);  // comes back
    workers = store.workers();
    EXPECT_EQ(workers[1].threads, 16);
    EXPECT_EQ(workers[1].first_seen, 100);
    EXPECT_EQ(workers[1].last_seen, 200);
    EXPECT_EQ(workers[1].samples_traced, 750);
    EXPECT_EQ(workers[1].state, "online");

    // Heard from by a coordinator it never registered with: the count is not lost.
    store.upsert_worker("w1", 0, 300);
    workers = store.workers();
    EXPECT_EQ(workers[1].threads, 16);
    EXPECT_EQ(workers[1].last_seen, 300);

    EXPECT_THROW(store.record_worker_samples("w9", 1, 1), StoreError);
    EXPECT_THROW(store.record_worker_samples("w1", -1, 1), StoreError);
    EXPECT_THROW(store.mark_worker_state("w9", "lost"), StoreError);
}

TEST_F(RunStoreTest, ConcurrentWritesFromEightThreadsAllLand) {
    RunStore store(dir);
    store.put_scene("h1", "cornell-box", "{}", 1);
    store.upsert_worker("w", 8, 1);
    constexpr int kThreads = 8, kRounds = 50;
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t) {
        threads.emplace_back([&store, t] {
            const std::string id = "r-" + std::to_string(t);
            store.create_render(render(id, t));
            for (int i = 0; i < kRounds; ++i) {
                store.add_round(round_of(id, i));
                store.record_worker_samples("w", 1, 2);
                store.update_render_progress(id, 100 * (i + 1), "{}");
            }
        });
    }
    for (auto& t : threads) t.join();

    EXPECT_EQ(store.list_renders(0).size(), size_t(kThreads));
    for (int t = 0; t < kThreads; ++t) {
        const std::string id = "r-" + std::to_string(t);
        const auto rounds = store.rounds(id);
        ASSERT_EQ(rounds.size(), size_t(kRounds)) << id;
        for (int i = 0; i < kRounds; ++i) EXPECT_EQ(rounds[i].idx, i);
        EXPECT_EQ(store.get_render(id)->samples_done, 100 * kRounds);
    }
    EXPECT_EQ(store.workers()[0].samples_traced, kThreads * kRounds);
    EXPECT_EQ(raw_query(db(), "SELECT COUNT(*) FROM rounds"),
              std::to_string(kThreads * kRounds));
}

TEST_F(RunStoreTest, CheckpointTruncatesTheWal) {
    RunStore store(dir);
    seed(store);
    for (int i = 0; i < 200; ++i) {
        RoundRecord r = round_of("r-1", i);
        r.buckets_json = std::string(4000, 'b');
        store.add_round(r);
    }
    ASSERT_GT(fs::file_size(wal()), 100'000u);
    const CheckpointResult result = store.checkpoint();
    EXPECT_FALSE(result.busy);
    EXPECT_EQ(result.wal_frames, result.checkpointed);
    EXPECT_EQ(fs::file_size(wal()), 0u);
    EXPECT_EQ(store.rounds("r-1").size(), 200u);
    store.add_round(round_of("r-1", 200));  // the store keeps working after it
    EXPECT_EQ(store.rounds("r-1").size(), 201u);
}

TEST_F(RunStoreTest, KeepsCommittedDataAfterACrash) {
    // The child writes and is killed with no destructor, checkpoint or close: the commits
    // exist only in the WAL.
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        try {
            RunStore store(dir);
            seed(store);
            for (int i = 0; i < 20; ++i) store.add_round(round_of("r-1", i));
            store.update_render_state("r-1", RenderState::Running, "", 15);
            raise(SIGKILL);  // while the store is open
        } catch (...) {
            _exit(1);
        }
        _exit(2);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL)
        << "the writer did not run to its kill (status " << status << ")";
    ASSERT_TRUE(fs::exists(wal()));
    EXPECT_GT(fs::file_size(wal()), 0u);

    RunStore store(dir);  // recovers the WAL and passes the integrity check
    const auto r = store.get_render("r-1");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->state, RenderState::Running);
    EXPECT_EQ(store.rounds("r-1").size(), 20u);
    EXPECT_EQ(store.unfinished_renders().size(), 1u);
}

TEST_F(RunStoreTest, IntegrityCheckPassesOnAHealthyDatabase) {
    {
        RunStore store(dir);
        seed(store);
        store.add_round(round_of("r-1", 0));
    }
    EXPECT_NO_THROW(RunStore store(dir));
    EXPECT_EQ(raw_query(db(), "PRAGMA integrity_check"), "ok");
}

TEST_F(RunStoreTest, RefusesADamagedDatabase) {
    {
        RunStore store(dir);
        store.put_scene("h1", "cornell-box", "{}", 1);
        for (int i = 0; i < 10; ++i)
            store.create_render(render("r-" + std::to_string(i), i));
    }
    // Redefine an index behind SQLite's back, so its entries no longer match the table.
    raw_query(db(),
              "PRAGMA writable_schema = ON;"
              "UPDATE sqlite_schema SET sql = 'CREATE INDEX renders_by_created ON "
              "renders(spec_json)' WHERE name = 'renders_by_created';");
    try {
        RunStore store(dir);
        FAIL() << "a damaged database was opened";
    } catch (const StoreError& e) {
        EXPECT_NE(std::string(e.what()).find("integrity"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("damaged"), std::string::npos) << e.what();
    }
}

TEST_F(RunStoreTest, RefusesAFileThatIsNotADatabase) {
    std::ofstream(db()) << std::string(8192, 'x');
    try {
        RunStore store(dir);
        FAIL() << "a file of junk was opened";
    } catch (const StoreError& e) {
        EXPECT_NE(std::string(e.what()).find(db().string()), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("not a database"), std::string::npos)
            << e.what();
    }
}

TEST_F(RunStoreTest, RefusesASchemaNewerThanThisBuild) {
    { RunStore store(dir); }
    raw_query(db(),
              "INSERT INTO schema_migrations (version, applied_at) VALUES (999, 0)");
    try {
        RunStore store(dir);
        FAIL() << "a database from a newer build was opened";
    } catch (const StoreError& e) {
        EXPECT_NE(std::string(e.what()).find("schema version 999"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace aliquot

namespace aliquot {
namespace {

TEST_F(RunStoreTest, APriorityIsStoredAndChanged) {
    RunStore store(dir);
    seed(store);
    RenderRecord high = render("r-2", 20);
    high.priority = 5;
    store.create_render(high);
    EXPECT_EQ(store.get_render("r-1")->priority, 0);
    EXPECT_EQ(store.get_render("r-2")->priority, 5);
    store.set_render_priority("r-1", -3);
    EXPECT_EQ(store.get_render("r-1")->priority, -3);
    EXPECT_THROW(store.set_render_priority("nope", 1), StoreError);
}

TEST_F(RunStoreTest, DeletingAFinishedRenderTakesItsRoundsAndItsSceneIfUnused) {
    RunStore store(dir);
    seed(store);
    store.create_render(render("r-2", 20));  // the same scene
    store.add_round(round_of("r-1", 0));
    // Neither may go while queued or running.
    EXPECT_FALSE(store.delete_render("r-1", 60));
    store.update_render_state("r-1", RenderState::Running, "", 30);
    EXPECT_FALSE(store.delete_render("r-1", 60));
    EXPECT_TRUE(store.get_render("r-1"));
    store.finish_render("r-1", RenderState::Done, "{}", 40);
    EXPECT_TRUE(store.delete_render("r-1", 60));
    EXPECT_FALSE(store.get_render("r-1"));
    EXPECT_TRUE(store.rounds("r-1").empty());
    EXPECT_TRUE(store.get_scene("h1")) << "r-2 still uses it";
    EXPECT_FALSE(store.delete_render("r-1", 60)) << "already gone";
    store.finish_render("r-2", RenderState::Cancelled, "{}", 50);
    EXPECT_TRUE(store.delete_render("r-2", 70));
    EXPECT_FALSE(store.get_scene("h1"));
    EXPECT_EQ(store.deleted_render_ids(), (std::vector<std::string>{"r-1", "r-2"}));
}

TEST_F(RunStoreTest, FinishedBeforeListsOnlyFinishedRendersOldestFirst) {
    RunStore store(dir);
    seed(store);
    for (const char* id : {"r-2", "r-3", "r-4"}) store.create_render(render(id, 20));
    store.finish_render("r-3", RenderState::Done, "{}", 300);
    store.finish_render("r-2", RenderState::Failed, "{}", 200);
    store.finish_render("r-4", RenderState::Done, "{}", 900);
    EXPECT_EQ(store.finished_before(500, 10), (std::vector<std::string>{"r-2", "r-3"}));
    EXPECT_EQ(store.finished_before(500, 1), (std::vector<std::string>{"r-2"}));
    EXPECT_TRUE(store.finished_before(100, 10).empty());
}

// Issue 30, item 5: a worker the coordinator forgot kept its row for ever.
TEST_F(RunStoreTest, ForgottenWorkersLoseTheirRows) {
    RunStore store(dir);
    store.upsert_worker("old", 1, 1000);
    store.upsert_worker("new", 1, 5000);
    store.upsert_worker("named", 1, 5000);
    EXPECT_EQ(store.forget_workers_silent_since(2000), 1u);
    store.forget_worker("named");
    store.forget_worker("never-there");  // nothing to do: no error
    const std::vector<WorkerRecord> rows = store.workers();
    ASSERT_EQ(rows.size(), 1u);
    EXPECT_EQ(rows[0].name, "new");
}

// Issue 30, item 10: under umask 022 aliquot.db and its -wal and -shm were 0644, readable
// by every local user. They are 0600 whatever the umask, and an older database is put
// right when it is opened.
TEST_F(RunStoreTest, TheDatabaseIsTheOwnersAloneWhateverTheUmask) {
    const mode_t before = ::umask(0);
    const auto private_file = fs::perms::owner_read | fs::perms::owner_write;
    {
        RunStore store(dir);
        store.upsert_worker("w", 1, 1000);  // the WAL and its index exist now
        for (const fs::path& p : {db(), wal(), fs::path(db().string() + "-shm")}) {
            ASSERT_TRUE(fs::exists(p)) << p;
            EXPECT_EQ(fs::status(p).permissions(), private_file) << p;
        }
    }
    fs::permissions(db(), fs::perms::all);  // as an older coordinator left it
    RunStore again(dir);
    EXPECT_EQ(fs::status(db()).permissions(), private_file);
    ::umask(before);
}

// A study database from before migration 7 (no mean bias columns) opens, gains them, and
// its rows read with no bias rather than a zero one; new rows keep theirs.
TEST_F(RunStoreTest, AStudyDatabaseFromBeforeTheMeanBiasLoadsWithoutIt) {
    { RunStore store(dir); }
    raw_query(
        db(),
        "DELETE FROM schema_migrations WHERE version = 7;"
        "ALTER TABLE study_results DROP COLUMN mean_bias;"
        "ALTER TABLE study_results DROP COLUMN mean_bias_se;"
        "ALTER TABLE study_results DROP COLUMN denoised_mean_bias;"
        "ALTER TABLE study_results DROP COLUMN denoised_mean_bias_se;"
        "INSERT INTO studies (id, name, definition_json, created_at)"
        " VALUES ('s@small', 's', '{}', 1);"
        "INSERT INTO study_results (study_id, render_key, spec_json, origin, remote_id,"
        " state, mean_abs, updated_at) VALUES ('s@small', 'u/0/1', '{}', 'embedded',"
        " 'r-1', 'done', 0.25, 1)");
    RunStore store(dir);
    EXPECT_EQ(store.schema_version(), RunStore::latest_schema_version());
    StudyResult fresh = store.study_results("s@small").at(0);
    EXPECT_EQ(fresh.mean_abs, 0.25);
    EXPECT_FALSE(fresh.mean_bias.has_value());
    EXPECT_FALSE(fresh.mean_bias_se.has_value());
    fresh.render_key = "u/1/1";
    fresh.mean_bias = -0.0168;
    fresh.mean_bias_se = 0.0004;
    store.put_study_result(fresh);
    EXPECT_EQ(store.study_results("s@small").at(1).mean_bias, -0.0168);
    EXPECT_EQ(store.study_results("s@small").at(1).mean_bias_se, 0.0004);
}

}  // namespace
}  // namespace aliquot
