// RunStore's schema: the numbered migrations, applied once each at open, and the
// schema version they leave (docs/STORE.md, "Migrations").
#include "store.h"

#include "store_internal.h"

namespace aliquot {

using store_internal::Transaction;

namespace {

// The schema, one migration per entry; migration N is entry N-1 and is applied once, in
// its own transaction, recorded in schema_migrations. Append only: a migration that has
// shipped is never edited, because databases in the field have already run it.
const char* const kMigrations[] = {
    // 1: scenes, renders and their rounds, workers.
    R"sql(
CREATE TABLE scenes (
    hash TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    json TEXT NOT NULL,
    created_at INTEGER NOT NULL
) STRICT;

CREATE TABLE renders (
    id TEXT PRIMARY KEY,
    scene_hash TEXT NOT NULL REFERENCES scenes(hash),
    spec_json TEXT NOT NULL,
    state TEXT NOT NULL
        CHECK (state IN ('queued', 'running', 'done', 'cancelled', 'failed')),
    error TEXT,
    created_at INTEGER NOT NULL,
    started_at INTEGER,
    finished_at INTEGER,
    samples_planned INTEGER NOT NULL CHECK (samples_planned >= 0),
    samples_done INTEGER NOT NULL CHECK (samples_done >= 0),
    strategy_state_json TEXT,
    outcome_json TEXT,
    reference_path TEXT
) STRICT;
CREATE INDEX renders_by_created ON renders(created_at);
CREATE INDEX renders_by_state ON renders(state, created_at);
CREATE INDEX renders_by_scene ON renders(scene_hash);

CREATE TABLE rounds (
    render_id TEXT NOT NULL REFERENCES renders(id) ON DELETE CASCADE,
    idx INTEGER NOT NULL CHECK (idx >= 0),
    samples_in_round INTEGER NOT NULL CHECK (samples_in_round >= 0),
    samples_total INTEGER NOT NULL CHECK (samples_total >= 0),
    seconds REAL NOT NULL,
    error_estimate REAL NOT NULL,
    error_vs_reference REAL,
    buckets_json TEXT,
    created_at INTEGER NOT NULL,
    PRIMARY KEY (render_id, idx)
) STRICT;

CREATE TABLE workers (
    name TEXT PRIMARY KEY,
    threads INTEGER NOT NULL CHECK (threads >= 0),
    first_seen INTEGER NOT NULL,
    last_seen INTEGER NOT NULL,
    samples_traced INTEGER NOT NULL DEFAULT 0 CHECK (samples_traced >= 0),
    state TEXT NOT NULL
) STRICT;
)sql",
    // 2: studies, groups of renders compared against each other.
    R"sql(
CREATE TABLE studies (
    id TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    definition_json TEXT NOT NULL,
    created_at INTEGER NOT NULL
) STRICT;

CREATE TABLE study_renders (
    study_id TEXT NOT NULL REFERENCES studies(id) ON DELETE CASCADE,
    render_id TEXT NOT NULL REFERENCES renders(id) ON DELETE CASCADE,
    PRIMARY KEY (study_id, render_id)
) STRICT;
CREATE INDEX study_renders_by_render ON study_renders(render_id);
)sql",
    // 3: a study's renders by key (group/index/seed): where they ran, what they measured.
    R"sql(
CREATE TABLE study_results (
    study_id TEXT NOT NULL REFERENCES studies(id) ON DELETE CASCADE,
    render_key TEXT NOT NULL,
    spec_json TEXT NOT NULL,
    origin TEXT NOT NULL,
    remote_id TEXT NOT NULL,
    render_id TEXT REFERENCES renders(id) ON DELETE SET NULL,
    state TEXT NOT NULL CHECK (state IN ('submitted', 'done')),
    samples INTEGER NOT NULL DEFAULT 0 CHECK (samples >= 0),
    rays INTEGER NOT NULL DEFAULT 0 CHECK (rays >= 0),
    seconds REAL NOT NULL DEFAULT 0,
    samples_per_second REAL NOT NULL DEFAULT 0,
    mean_abs REAL,
    rmse REAL,
    relative_mse REAL,
    max_bucket REAL,
    p99_bucket REAL,
    outcome_json TEXT,
    updated_at INTEGER NOT NULL,
    PRIMARY KEY (study_id, render_key)
) STRICT;
)sql",
    // 4: a render's priority (leases go to the highest first), and finished renders by
    // time for the retention policy.
    R"sql(
ALTER TABLE renders ADD COLUMN priority INTEGER NOT NULL DEFAULT 0;
CREATE INDEX renders_by_finished ON renders(finished_at) WHERE finished_at IS NOT NULL;

-- Renders deleted (by a client or the retention policy): when, and so that their ids
-- are never handed out again.
CREATE TABLE deleted_renders (
    id TEXT PRIMARY KEY,
    deleted_at INTEGER NOT NULL
) STRICT;
)sql",
    // 5: what happened to each render (coordinator/farm/render_events.h), numbered per
    // render from 0; the coordinator keeps the first and last few (a gap in seq:
    // dropped).
    R"sql(
CREATE TABLE render_events (
    render_id TEXT NOT NULL REFERENCES renders(id) ON DELETE CASCADE,
    seq INTEGER NOT NULL CHECK (seq >= 0),
    at_ms INTEGER NOT NULL,
    kind TEXT NOT NULL,
    fields_json TEXT NOT NULL,
    PRIMARY KEY (render_id, seq)
) STRICT;
)sql",
    // 6: a study's renders measured after denoising too (issue 34): E, RMSE and relative
    // MSE of the render denoised by Open Image Denoise, against the same reference; NULL
    // for a study that does not denoise.
    R"sql(
ALTER TABLE study_results ADD COLUMN denoised_mean_abs REAL;
ALTER TABLE study_results ADD COLUMN denoised_rmse REAL;
ALTER TABLE study_results ADD COLUMN denoised_relative_mse REAL;
)sql",
    // 7: a study's renders' mean bias against the reference and its standard error
    // (coordinator/image/error_metric.h), raw and denoised: E alone rewards an image too
    // dark. NULL for the rows of earlier runs, which did not measure it.
    R"sql(
ALTER TABLE study_results ADD COLUMN mean_bias REAL;
ALTER TABLE study_results ADD COLUMN mean_bias_se REAL;
ALTER TABLE study_results ADD COLUMN denoised_mean_bias REAL;
ALTER TABLE study_results ADD COLUMN denoised_mean_bias_se REAL;
)sql",
    // 8: each round's mean bias against the render's reference and its standard error,
    // beside its E: E falls as a biased method converges while its image stays too dark.
    // NULL without a reference, where there is no bias (a black reference), and for the
    // rounds of earlier coordinators, which did not measure it.
    R"sql(
ALTER TABLE rounds ADD COLUMN mean_bias REAL;
ALTER TABLE rounds ADD COLUMN mean_bias_se REAL;
)sql",
};

constexpr int kLatestVersion = int(sizeof(kMigrations) / sizeof(kMigrations[0]));

}  // namespace

void RunStore::migrate() {
    exec(
        "CREATE TABLE IF NOT EXISTS schema_migrations ("
        " version INTEGER PRIMARY KEY, applied_at INTEGER NOT NULL) STRICT",
        "create schema_migrations in " + path_.string());
    const int current = schema_version();
    if (current > kLatestVersion)
        throw StoreError("store: " + path_.string() + " has schema version " +
                         std::to_string(current) + " but this build knows only up to " +
                         std::to_string(kLatestVersion) + "; run a newer aliquot");

    const auto applied = [this](int version, const std::string& purpose) {
        Query q = query("SELECT 1 FROM schema_migrations WHERE version = ?", purpose);
        return q.bind(version).step();
    };
    for (int version = 1; version <= kLatestVersion; ++version) {
        const std::string purpose =
            "apply migration " + std::to_string(version) + " to " + path_.string();
        if (applied(version, purpose)) continue;
        Transaction tx(db_->db, purpose);
        // Asked again under the write lock: another process may have just applied it.
        if (applied(version, purpose)) continue;
        exec(kMigrations[version - 1], purpose);
        {
            Query q = query("PRAGMA foreign_key_check", purpose);
            if (q.step())
                q.refuse("it leaves a row of " + q.text(0) + " violating a foreign key");
        }
        query("INSERT INTO schema_migrations (version, applied_at) VALUES (?, ?)",
              purpose)
            .bind(version)
            .bind(unix_millis_now())
            .run();
        tx.commit(purpose);
    }
}

int RunStore::latest_schema_version() { return kLatestVersion; }

int RunStore::schema_version() {
    std::lock_guard lock(mutex_);
    Query q = query("SELECT COALESCE(MAX(version), 0) FROM schema_migrations",
                    "read the schema version");
    return q.step() ? static_cast<int>(q.int64(0)) : 0;
}

}  // namespace aliquot
