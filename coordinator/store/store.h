// RunStore: the coordinator's durable record of scenes, renders, rounds and workers, kept
// in one SQLite database (DIR/aliquot.db, WAL). No SQL lives outside this room's
// store*.cpp files (one concern each; store_internal.h lists them); see docs/STORE.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "render_state.h"
#include "unix_millis.h"

struct sqlite3;

namespace aliquot {

// Every failure of the store: the SQLite message prefixed by what the store was doing,
// e.g. "store: cannot add round 3 of render r-12: FOREIGN KEY constraint failed".
class StoreError : public std::runtime_error {
public:
    StoreError(const std::string& message, int sqlite_code = 0)
        : std::runtime_error(message), sqlite_code_(sqlite_code) {}
    // The extended SQLite result code, or 0 when the store itself refused (bad argument,
    // conflicting data, failed integrity check).
    int sqlite_code() const { return sqlite_code_; }

private:
    int sqlite_code_;
};

// Optional text columns are NULL in the database and empty strings here.
struct SceneRecord {
    std::string hash;  // content hash of `json`: the scene's identity
    std::string name;
    std::string json;
    int64_t created_at = 0;
};

struct RenderRecord {
    std::string id;
    std::string scene_hash;  // must name a stored scene
    std::string spec_json;   // method, parameters, budget, resolution, seed
    RenderState state = RenderState::Queued;
    std::string error;  // why it failed; empty otherwise
    int64_t created_at = 0;
    std::optional<int64_t> started_at;   // first time it became Running
    std::optional<int64_t> finished_at;  // when it reached a terminal state
    int64_t samples_planned = 0;
    int64_t samples_done = 0;
    std::string strategy_state_json;  // what the strategy needs to resume
    std::string outcome_json;         // final statistics, written by finish_render
    std::string reference_path;  // reference EXR the per-round error is measured against
    int64_t priority = 0;        // leases go to the highest first (changeable)
};

struct RoundRecord {
    std::string render_id;
    int64_t idx = 0;  // 0-based round number within the render
    int64_t samples_in_round = 0;
    int64_t samples_total = 0;  // samples merged into the render after this round
    double seconds = 0;         // wall time since the render started
    double error_estimate = 0;  // the strategy's own estimate (even/odd halves)
    std::optional<double> error_vs_reference;
    // The image's mean bias against the reference and its standard error (a fraction,
    // error_metric.h); absent without a reference or where there is none.
    std::optional<double> mean_bias, mean_bias_se;
    std::string buckets_json;  // per-bucket state, when the strategy has buckets
    int64_t created_at = 0;
};

struct WorkerRecord {
    std::string name;
    int64_t threads = 0;
    int64_t first_seen = 0;
    int64_t last_seen = 0;
    int64_t samples_traced = 0;
    std::string state;  // "online" after upsert_worker; others ("lost", "left") are the
                        // coordinator's to choose
};

// The outcome of `PRAGMA wal_checkpoint(TRUNCATE)`.
struct CheckpointResult {
    // Another connection kept it from completing; the next call tries again.
    bool busy = false;
    // Frames in the WAL before the checkpoint (-1 if the database is not in WAL mode).
    int wal_frames = 0;
    // Frames copied into the database.
    int checkpointed = 0;
};

// A study (docs/STUDIES.md): its id is "name@scale".
struct StudyRecord {
    std::string id;
    std::string name;
    std::string definition_json;
    int64_t created_at = 0;
};

// One render of a study, by its key (group/index/seed): the spec it was rendered with,
// where it ran (origin "embedded" or "farm ADDR", remote_id the id there), the local
// render record once there is one, and what it measured against the reference.
struct StudyResult {
    std::string study_id, render_key, spec_json, origin, remote_id;
    std::string render_id;  // local renders.id; empty until recorded
    std::string state;      // "submitted" or "done"
    int64_t samples = 0, rays = 0;
    double seconds = 0, samples_per_second = 0;
    std::optional<double> mean_abs, rmse, relative_mse, max_bucket, p99_bucket;
    // The same after denoising (a study with "denoise"); empty for any other.
    std::optional<double> denoised_mean_abs, denoised_rmse, denoised_relative_mse;
    // The image's mean bias against the reference and its standard error (fractions, as
    // ErrorMetrics has them), raw and denoised; empty for rows recorded before
    // migration 7, for a black reference or an image holding NaN or inf, and (the
    // standard error alone) for an image too small to cut into blocks.
    std::optional<double> mean_bias, mean_bias_se, denoised_mean_bias,
        denoised_mean_bias_se;
    std::string outcome_json;
    int64_t updated_at = 0;
};

// One event of a render (coordinator/farm/render_events.h): its number within the render
// (from 0), when, its kind's spelling and its fields as a JSON object.
struct RenderEventRecord {
    std::string render_id;
    int64_t seq = 0;
    int64_t at_ms = 0;
    std::string kind;
    std::string fields_json;
};

// One connection, guarded by a mutex: every method may be called from any thread. Each
// method is one transaction; a method that returns has made its change durable against a
// process crash (a power loss may lose the last commits: synchronous=NORMAL).
class RunStore {
public:
    // Opens (creating if needed) `data_dir`/aliquot.db, sets WAL, foreign keys, busy
    // timeout and synchronous=NORMAL, makes the database and its -wal and -shm files
    // mode 0600 whatever the umask (SQLite gives those two the database's mode), refuses
    // a database whose integrity check fails or whose schema is newer than this build,
    // and applies pending migrations.
    explicit RunStore(const std::filesystem::path& data_dir);
    ~RunStore();
    RunStore(const RunStore&) = delete;
    RunStore& operator=(const RunStore&) = delete;

    const std::filesystem::path& path() const { return path_; }
    // Highest migration applied; equals latest_schema_version() after construction.
    int schema_version();
    static int latest_schema_version();

    // Copies the WAL into the database and truncates it to zero bytes, so the WAL cannot
    // grow without bound. The coordinator calls it periodically.
    CheckpointResult checkpoint();

    // Stores a scene once. Returns false (and changes nothing) if `hash` is already
    // stored with the same json; throws if it is stored with different json.
    bool put_scene(const std::string& hash, const std::string& name,
                   const std::string& json, int64_t now_ms);
    std::optional<SceneRecord> get_scene(const std::string& hash);

    // Inserts a new render; throws if the id exists or the scene is unknown.
    void create_render(const RenderRecord& render);
    // Sets the state and error (empty: none). Running stamps started_at once; a terminal
    // state stamps finished_at; a non-terminal one clears it, but never replaces a
    // terminal one (a late "running" after a cancel). The coordinator owns which other
    // transitions are allowed. Throws if the render is unknown.
    void update_render_state(const std::string& id, RenderState state,
                             const std::string& error, int64_t now_ms);
    void update_render_progress(const std::string& id, int64_t samples_done,
                                const std::string& strategy_state_json);
    // Throws "no such render" for an unknown id.
    void set_render_priority(const std::string& id, int64_t priority);
    // Deletes a finished render's row, its rounds and its study links, and its scene
    // when no other render uses it, and notes its id as deleted; false (nothing changes)
    // when there is no such finished render (unknown, queued or running).
    bool delete_render(const std::string& id, int64_t now_ms);
    // Every id delete_render took: never to be handed out again.
    std::vector<std::string> deleted_render_ids();
    // Finished renders that finished before `before_ms`, oldest first, at most `limit`.
    std::vector<std::string> finished_before(int64_t before_ms, size_t limit);
    // Whether any render is judged against the reference image at `path`.
    bool reference_in_use(const std::string& path);
    // Moves a render to a terminal state (throws for Queued/Running) with its outcome.
    void finish_render(const std::string& id, RenderState state,
                       const std::string& outcome_json, int64_t now_ms);
    std::optional<RenderRecord> get_render(const std::string& id);
    // Newest first (created_at, then insertion order); limit 0 means all.
    std::vector<RenderRecord> list_renders(
        size_t limit, std::optional<RenderState> state = std::nullopt);
    // How many renders are in each state (states with none are absent): one query
    // however many renders the record holds, for the coordinator's metrics.
    std::map<RenderState, uint64_t> count_renders_by_state();
    // Queued and Running renders, oldest first: what a restarted coordinator resumes.
    std::vector<RenderRecord> unfinished_renders();

    // Records a round. Recording (render_id, idx) again is a no-op returning false, so a
    // restarted coordinator may re-record a round; wall-clock fields (seconds,
    // created_at) may differ, but different sample counts mean a different round and
    // throw.
    bool add_round(const RoundRecord& round);
    // In round order.
    std::vector<RoundRecord> rounds(const std::string& render_id);
    // The highest-numbered round, without reading the others.
    std::optional<RoundRecord> last_round(const std::string& render_id);

    // Registers a worker or refreshes it: threads, last_seen and state "online". Threads
    // 0 means unknown and keeps the count already recorded.
    void upsert_worker(const std::string& name, int64_t threads, int64_t now_ms);
    // Adds to a known worker's samples_traced and refreshes last_seen.
    void record_worker_samples(const std::string& name, int64_t samples, int64_t now_ms);
    // Sets the state only; last_seen keeps the time the worker was last heard from.
    void mark_worker_state(const std::string& name, const std::string& state);
    // By name.
    std::vector<WorkerRecord> workers();
    // Deletes a worker's row (the coordinator forgot it); nothing when there is none.
    void forget_worker(const std::string& name);
    // Deletes the rows of workers last seen before `before_ms`; how many.
    size_t forget_workers_silent_since(int64_t before_ms);

private:
    class Query;
    struct Connection;

    // A cached prepared statement for `sql`; `purpose` names it in errors ("add round 3
    // of render r-12").
    Query query(const std::string& sql, std::string purpose);
    static RoundRecord round_from_row(Query& q);
    void exec(const std::string& sql, const std::string& purpose);
    void configure();
    void check_integrity();
    void migrate();

    std::filesystem::path path_;
    std::mutex mutex_;
    std::unique_ptr<Connection> db_;

    // ---- Studies (aliquot study) ----
public:
    // Inserts a study or replaces its name and definition.
    void put_study(const StudyRecord& study);
    std::optional<StudyRecord> get_study(const std::string& id);
    // Adds (study, render) to study_renders; linking again is a no-op.
    void link_study_render(const std::string& study_id, const std::string& render_id);
    // Inserts or replaces the row of (study_id, render_key). Non-finite metrics become
    // NULL.
    void put_study_result(const StudyResult& result);
    // In the order they were first recorded.
    std::vector<StudyResult> study_results(const std::string& study_id);
    // Forgets one key (the study file no longer has it); its render record stays.
    void remove_study_result(const std::string& study_id, const std::string& render_key);

    // ---- A render's events (coordinator/farm/render_events.h) ----
    // Records an event (again: a no-op) and deletes the render's events numbered from
    // keep_first to e.seq - keep_last, so a render keeps at most keep_first + keep_last.
    void add_render_event(const RenderEventRecord& e, int64_t keep_first,
                          int64_t keep_last);
    // Those numbered after `after_seq`, in order, at most `limit`.
    std::vector<RenderEventRecord> render_events(const std::string& render_id,
                                                 int64_t after_seq, size_t limit);
    // How many events of the render are kept, and the highest number (-1: none).
    std::pair<int64_t, int64_t> render_event_span(const std::string& render_id);
};

}  // namespace aliquot
