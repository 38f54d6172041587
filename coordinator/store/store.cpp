// RunStore on the SQLite C API: one connection, cached prepared statements, numbered
// migrations. The schema and the reasons for the pragmas are in docs/STORE.md.
#include "store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <concepts>
#include <cstring>
#include <system_error>
#include <unordered_map>

namespace aliquot {

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
};

constexpr int kLatestVersion = int(sizeof(kMigrations) / sizeof(kMigrations[0]));

const std::string kRenderColumns =
    "id, scene_hash, spec_json, state, error, created_at, started_at, finished_at, "
    "samples_planned, samples_done, strategy_state_json, outcome_json, reference_path, "
    "priority";

const std::string kRoundColumns =
    "render_id, idx, samples_in_round, samples_total, seconds, error_estimate, "
    "error_vs_reference, buckets_json, created_at";

// Optional text: empty in the records, NULL in the database.
std::optional<std::string_view> or_null(const std::string& text) {
    if (text.empty()) return std::nullopt;
    return text;
}

}  // namespace

// The connection and its prepared statements, finalized before the connection closes.
struct RunStore::Connection {
    sqlite3* db = nullptr;
    std::unordered_map<std::string, sqlite3_stmt*> statements;

    ~Connection() {
        for (auto& [sql, stmt] : statements) sqlite3_finalize(stmt);
        // Closing the last connection checkpoints the WAL and removes it.
        sqlite3_close_v2(db);
    }
};

// One use of a cached statement: binds parameters in order, steps, reads columns, and
// resets the statement when it goes out of scope. Failures throw StoreError naming the
// purpose.
class RunStore::Query {
public:
    Query(sqlite3* db, sqlite3_stmt* stmt, std::string purpose)
        : db_(db), stmt_(stmt), purpose_(std::move(purpose)) {}
    ~Query() {
        sqlite3_reset(stmt_);
        sqlite3_clear_bindings(stmt_);
    }
    Query(const Query&) = delete;
    Query& operator=(const Query&) = delete;

    template <std::integral T>
    Query& bind(T value) {
        check(sqlite3_bind_int64(stmt_, ++index_, static_cast<sqlite3_int64>(value)));
        return *this;
    }
    Query& bind(double value) {
        check(sqlite3_bind_double(stmt_, ++index_, value));
        return *this;
    }
    Query& bind(std::string_view text) {
        // A null data pointer would bind NULL, not the empty string.
        check(sqlite3_bind_text(stmt_, ++index_, text.data() ? text.data() : "",
                                static_cast<int>(text.size()), SQLITE_TRANSIENT));
        return *this;
    }
    Query& bind(const char* text) { return bind(std::string_view(text)); }
    Query& bind(const std::string& text) { return bind(std::string_view(text)); }
    Query& bind(std::nullopt_t) {
        check(sqlite3_bind_null(stmt_, ++index_));
        return *this;
    }
    template <class T>
    Query& bind(const std::optional<T>& value) {
        return value ? bind(*value) : bind(std::nullopt);
    }

    // True while a row is available.
    bool step() {
        const int rc = sqlite3_step(stmt_);
        if (rc == SQLITE_ROW) return true;
        if (rc == SQLITE_DONE) return false;
        fail(rc);
    }
    // Runs a statement to completion; returns the number of rows it changed.
    int run() {
        while (step()) {
        }
        return sqlite3_changes(db_);
    }

    int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
    double real(int col) const { return sqlite3_column_double(stmt_, col); }
    std::string text(int col) const {
        const auto* p = sqlite3_column_text(stmt_, col);
        if (!p) return {};
        return std::string(reinterpret_cast<const char*>(p),
                           static_cast<size_t>(sqlite3_column_bytes(stmt_, col)));
    }
    bool is_null(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
    std::optional<int64_t> maybe_int64(int col) const {
        if (is_null(col)) return std::nullopt;
        return int64(col);
    }
    std::optional<double> maybe_real(int col) const {
        if (is_null(col)) return std::nullopt;
        return real(col);
    }

    // The store refuses for a reason of its own.
    [[noreturn]] void refuse(const std::string& why) const {
        throw StoreError("store: cannot " + purpose_ + ": " + why);
    }

private:
    void check(int rc) const {
        if (rc != SQLITE_OK) fail(rc);
    }
    [[noreturn]] void fail(int rc) const {
        throw StoreError(
            "store: cannot " + purpose_ + ": " + sqlite3_errmsg(db_),
            sqlite3_extended_errcode(db_) ? sqlite3_extended_errcode(db_) : rc);
    }

    sqlite3* db_;
    sqlite3_stmt* stmt_;
    std::string purpose_;
    int index_ = 0;
};

RunStore::Query RunStore::query(const std::string& sql, std::string purpose) {
    auto it = db_->statements.find(sql);
    if (it == db_->statements.end()) {
        sqlite3_stmt* stmt = nullptr;
        const int rc =
            sqlite3_prepare_v3(db_->db, sql.c_str(), static_cast<int>(sql.size()),
                               SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
        if (rc != SQLITE_OK) {
            sqlite3_finalize(stmt);
            throw StoreError("store: cannot " + purpose + ": " + sqlite3_errmsg(db_->db),
                             sqlite3_extended_errcode(db_->db));
        }
        it = db_->statements.emplace(sql, stmt).first;
    }
    return Query(db_->db, it->second, std::move(purpose));
}

void RunStore::exec(const std::string& sql, const std::string& purpose) {
    char* message = nullptr;
    const int rc = sqlite3_exec(db_->db, sql.c_str(), nullptr, nullptr, &message);
    if (rc != SQLITE_OK) {
        std::string text = message ? message : sqlite3_errstr(rc);
        sqlite3_free(message);
        throw StoreError("store: cannot " + purpose + ": " + text,
                         sqlite3_extended_errcode(db_->db));
    }
}

namespace {

// BEGIN IMMEDIATE takes the write lock at once, so a transaction never fails half-way on
// a lock upgrade; a transaction not committed is rolled back.
class Transaction {
public:
    Transaction(sqlite3* db, const std::string& purpose) : db_(db) {
        run("BEGIN IMMEDIATE", purpose);
    }
    ~Transaction() {
        if (open_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void commit(const std::string& purpose) {
        run("COMMIT", purpose);
        open_ = false;
    }

private:
    void run(const char* sql, const std::string& purpose) {
        const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
        if (rc != SQLITE_OK)
            throw StoreError("store: cannot " + purpose + ": " + sqlite3_errmsg(db_),
                             sqlite3_extended_errcode(db_));
        open_ = true;
    }

    sqlite3* db_;
    bool open_ = false;
};

}  // namespace

RunStore::RunStore(const std::filesystem::path& data_dir)
    : path_(data_dir / "aliquot.db"), db_(std::make_unique<Connection>()) {
    std::error_code ec;
    std::filesystem::create_directories(data_dir, ec);
    if (ec)
        throw StoreError("store: cannot create data directory " + data_dir.string() +
                         ": " + ec.message());

    // The record is the farm's users' scenes and renders: the owner's alone, whatever
    // the umask. SQLite creates the database with 0644 less the umask and gives its -wal
    // and -shm files the database's mode, so it is made 0600 first; a database an older
    // coordinator made, and its -wal and -shm, are put right. By path, never through a
    // descriptor of an existing file: closing one would drop the POSIX locks another
    // connection of this process holds on it.
    const int fd =
        ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, S_IRUSR | S_IWUSR);
    if (fd >= 0)
        ::close(fd);  // new and empty: SQLite makes it a database
    else if (errno != EEXIST)
        throw StoreError("store: cannot create " + path_.string() + ": " +
                         std::strerror(errno));
    // Best effort on a file another user owns: its mode is theirs to keep.
    for (const char* suffix : {"", "-wal", "-shm"})
        ::chmod((path_.string() + suffix).c_str(), S_IRUSR | S_IWUSR);

    // The connection is used by one thread at a time (mutex_), so SQLite's own mutex
    // would only cost.
    const int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
    const int rc = sqlite3_open_v2(path_.c_str(), &db_->db, flags, nullptr);
    if (rc != SQLITE_OK) {
        const std::string message =
            db_->db ? sqlite3_errmsg(db_->db) : sqlite3_errstr(rc);
        throw StoreError("store: cannot open " + path_.string() + ": " + message, rc);
    }
    sqlite3_extended_result_codes(db_->db, 1);

    configure();
    check_integrity();
    migrate();
}

RunStore::~RunStore() = default;

void RunStore::configure() {
    const std::string where = " on " + path_.string();
    // First, so that the pragmas below wait for another process's lock instead of
    // failing.
    query("PRAGMA busy_timeout = 5000", "set the busy timeout" + where).run();
    {
        Query q = query("PRAGMA journal_mode = WAL", "set WAL journal mode" + where);
        const std::string mode = q.step() ? q.text(0) : "";
        if (mode != "wal")
            q.refuse("the journal mode is '" + mode +
                     "' (WAL needs a local file system with shared memory)");
    }
    query("PRAGMA synchronous = NORMAL", "set synchronous mode" + where).run();
    // A per-connection setting, off by default in SQLite, and a no-op inside a
    // transaction.
    query("PRAGMA foreign_keys = ON", "enable foreign keys" + where).run();
}

void RunStore::check_integrity() {
    Query q = query("PRAGMA integrity_check", "check the integrity of " + path_.string());
    std::string problems;
    int count = 0;
    while (q.step()) {
        const std::string line = q.text(0);
        if (line == "ok") continue;
        if (++count <= 5) problems += (problems.empty() ? "" : "; ") + line;
    }
    if (count > 5) problems += "; and " + std::to_string(count - 5) + " more";
    if (count > 0)
        q.refuse("the database is damaged (" + problems +
                 "); restore a backup or move the file aside to start afresh");
}

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

CheckpointResult RunStore::checkpoint() {
    std::lock_guard lock(mutex_);
    Query q = query("PRAGMA wal_checkpoint(TRUNCATE)", "checkpoint the WAL");
    CheckpointResult result;
    if (q.step()) {
        result.busy = q.int64(0) != 0;
        result.wal_frames = static_cast<int>(q.int64(1));
        result.checkpointed = static_cast<int>(q.int64(2));
    }
    return result;
}

// --- scenes

bool RunStore::put_scene(const std::string& hash, const std::string& name,
                         const std::string& json, int64_t now_ms) {
    std::lock_guard lock(mutex_);
    const std::string purpose = "store scene " + hash;
    const int inserted = query(
                             "INSERT INTO scenes (hash, name, json, created_at) "
                             "VALUES (?, ?, ?, ?) ON CONFLICT (hash) DO NOTHING",
                             purpose)
                             .bind(hash)
                             .bind(name)
                             .bind(json)
                             .bind(now_ms)
                             .run();
    if (inserted) return true;
    Query q = query("SELECT json FROM scenes WHERE hash = ?", purpose);
    if (q.bind(hash).step() && q.text(0) != json)
        q.refuse("a different scene is already stored under this hash");
    return false;
}

std::optional<SceneRecord> RunStore::get_scene(const std::string& hash) {
    std::lock_guard lock(mutex_);
    Query q = query("SELECT hash, name, json, created_at FROM scenes WHERE hash = ?",
                    "read scene " + hash);
    if (!q.bind(hash).step()) return std::nullopt;
    return SceneRecord{q.text(0), q.text(1), q.text(2), q.int64(3)};
}

// --- renders

namespace {

template <class Q>
RenderRecord read_render(const Q& q) {
    RenderRecord r;
    r.id = q.text(0);
    r.scene_hash = q.text(1);
    r.spec_json = q.text(2);
    const std::string state = q.text(3);
    const auto parsed = parse_render_state(state);
    if (!parsed) q.refuse("render " + r.id + " has unknown state '" + state + "'");
    r.state = *parsed;
    r.error = q.text(4);
    r.created_at = q.int64(5);
    r.started_at = q.maybe_int64(6);
    r.finished_at = q.maybe_int64(7);
    r.samples_planned = q.int64(8);
    r.samples_done = q.int64(9);
    r.strategy_state_json = q.text(10);
    r.outcome_json = q.text(11);
    r.reference_path = q.text(12);
    r.priority = q.int64(13);
    return r;
}

}  // namespace

void RunStore::create_render(const RenderRecord& r) {
    std::lock_guard lock(mutex_);
    static const std::string sql = "INSERT INTO renders (" + kRenderColumns +
                                   ") VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";
    query(sql, "create render " + r.id)
        .bind(r.id)
        .bind(r.scene_hash)
        .bind(r.spec_json)
        .bind(to_string(r.state))
        .bind(or_null(r.error))
        .bind(r.created_at)
        .bind(r.started_at)
        .bind(r.finished_at)
        .bind(r.samples_planned)
        .bind(r.samples_done)
        .bind(or_null(r.strategy_state_json))
        .bind(or_null(r.outcome_json))
        .bind(or_null(r.reference_path))
        .bind(r.priority)
        .run();
}

void RunStore::set_render_priority(const std::string& id, int64_t priority) {
    std::lock_guard lock(mutex_);
    Query q = query("UPDATE renders SET priority = ? WHERE id = ?",
                    "set the priority of render " + id);
    if (q.bind(priority).bind(id).run() == 0) q.refuse("no such render");
}

bool RunStore::delete_render(const std::string& id, int64_t now_ms) {
    std::lock_guard lock(mutex_);
    const std::string purpose = "delete render " + id;
    Transaction tx(db_->db, purpose);
    std::string scene;
    {
        Query q = query(
            "SELECT scene_hash FROM renders WHERE id = ?"
            " AND state NOT IN ('queued', 'running')",
            purpose);
        if (!q.bind(id).step()) return false;
        scene = q.text(0);
    }
    // Its rounds and study links go with it (ON DELETE CASCADE); a study's result keeps
    // its numbers and loses only the link (SET NULL).
    query("DELETE FROM renders WHERE id = ?", purpose).bind(id).run();
    query("INSERT OR REPLACE INTO deleted_renders (id, deleted_at) VALUES (?, ?)",
          purpose)
        .bind(id)
        .bind(now_ms)
        .run();
    // A scene no render uses any more is dead weight: scenes are kept for renders only.
    query(
        "DELETE FROM scenes WHERE hash = ?"
        " AND NOT EXISTS (SELECT 1 FROM renders WHERE scene_hash = ?)",
        purpose)
        .bind(scene)
        .bind(scene)
        .run();
    tx.commit(purpose);
    return true;
}

std::vector<std::string> RunStore::finished_before(int64_t before_ms, size_t limit) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "SELECT id FROM renders WHERE finished_at IS NOT NULL AND finished_at < ?"
        " AND state NOT IN ('queued', 'running') ORDER BY finished_at LIMIT ?",
        "list renders finished before " + std::to_string(before_ms));
    q.bind(before_ms).bind(static_cast<int64_t>(limit));
    std::vector<std::string> ids;
    while (q.step()) ids.push_back(q.text(0));
    return ids;
}

std::vector<std::string> RunStore::deleted_render_ids() {
    std::lock_guard lock(mutex_);
    Query q = query("SELECT id FROM deleted_renders", "list deleted renders");
    std::vector<std::string> ids;
    while (q.step()) ids.push_back(q.text(0));
    return ids;
}

bool RunStore::reference_in_use(const std::string& path) {
    std::lock_guard lock(mutex_);
    Query q = query("SELECT 1 FROM renders WHERE reference_path = ? LIMIT 1",
                    "look for renders judged against " + path);
    return q.bind(path).step();
}

void RunStore::update_render_state(const std::string& id, RenderState state,
                                   const std::string& error, int64_t now_ms) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "UPDATE renders SET state = ?, error = ?,"
        " started_at = CASE WHEN ? THEN COALESCE(started_at, ?) ELSE started_at END,"
        " finished_at = ? WHERE id = ?",
        "set render " + id + " " + std::string(to_string(state)));
    q.bind(to_string(state))
        .bind(or_null(error))
        .bind(state == RenderState::Running)
        .bind(now_ms);
    if (is_terminal(state))
        q.bind(now_ms);
    else
        q.bind(std::nullopt);
    if (q.bind(id).run() == 0) q.refuse("no such render");
}

void RunStore::update_render_progress(const std::string& id, int64_t samples_done,
                                      const std::string& strategy_state_json) {
    std::lock_guard lock(mutex_);
    Query q =
        query("UPDATE renders SET samples_done = ?, strategy_state_json = ? WHERE id = ?",
              "record progress of render " + id);
    if (q.bind(samples_done).bind(or_null(strategy_state_json)).bind(id).run() == 0)
        q.refuse("no such render");
}

void RunStore::finish_render(const std::string& id, RenderState state,
                             const std::string& outcome_json, int64_t now_ms) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "UPDATE renders SET state = ?, outcome_json = ?, finished_at = ? WHERE id = ?",
        "finish render " + id + " as " + std::string(to_string(state)));
    if (!is_terminal(state))
        q.refuse("a finished render must be done, cancelled or failed");
    if (q.bind(to_string(state))
            .bind(or_null(outcome_json))
            .bind(now_ms)
            .bind(id)
            .run() == 0)
        q.refuse("no such render");
}

std::optional<RenderRecord> RunStore::get_render(const std::string& id) {
    std::lock_guard lock(mutex_);
    static const std::string sql =
        "SELECT " + kRenderColumns + " FROM renders WHERE id = ?";
    Query q = query(sql, "read render " + id);
    if (!q.bind(id).step()) return std::nullopt;
    return read_render(q);
}

std::vector<RenderRecord> RunStore::list_renders(size_t limit,
                                                 std::optional<RenderState> state) {
    std::lock_guard lock(mutex_);
    static const std::string all = "SELECT " + kRenderColumns +
                                   " FROM renders ORDER BY created_at DESC, rowid DESC"
                                   " LIMIT ?";
    static const std::string filtered = "SELECT " + kRenderColumns +
                                        " FROM renders WHERE state = ?"
                                        " ORDER BY created_at DESC, rowid DESC LIMIT ?";
    Query q = query(state ? filtered : all, "list renders");
    if (state) q.bind(to_string(*state));
    // LIMIT -1: no limit.
    q.bind(limit == 0 ? int64_t{-1} : static_cast<int64_t>(limit));
    std::vector<RenderRecord> renders;
    while (q.step()) renders.push_back(read_render(q));
    return renders;
}

std::map<RenderState, uint64_t> RunStore::count_renders_by_state() {
    std::lock_guard lock(mutex_);
    Query q = query("SELECT state, COUNT(*) FROM renders GROUP BY state",
                    "count renders by state");
    std::map<RenderState, uint64_t> counts;
    while (q.step()) {
        const std::string state = q.text(0);
        const auto parsed = parse_render_state(state);
        if (!parsed) q.refuse("a render has unknown state '" + state + "'");
        counts[*parsed] = uint64_t(q.int64(1));
    }
    return counts;
}

std::vector<RenderRecord> RunStore::unfinished_renders() {
    std::lock_guard lock(mutex_);
    static const std::string sql = "SELECT " + kRenderColumns +
                                   " FROM renders WHERE state IN ('queued', 'running')"
                                   " ORDER BY created_at, rowid";
    Query q = query(sql, "list unfinished renders");
    std::vector<RenderRecord> renders;
    while (q.step()) renders.push_back(read_render(q));
    return renders;
}

// --- rounds

bool RunStore::add_round(const RoundRecord& r) {
    std::lock_guard lock(mutex_);
    static const std::string sql = "INSERT INTO rounds (" + kRoundColumns +
                                   ") VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)"
                                   " ON CONFLICT (render_id, idx) DO NOTHING";
    Query q =
        query(sql, "add round " + std::to_string(r.idx) + " of render " + r.render_id);
    // SQLite stores NaN as NULL; refuse it here with a message that says so.
    if (!std::isfinite(r.seconds)) q.refuse("its seconds are not finite");
    if (!std::isfinite(r.error_estimate)) q.refuse("its error estimate is not finite");
    if (r.error_vs_reference && !std::isfinite(*r.error_vs_reference))
        q.refuse("its error against the reference is not finite");
    const int inserted = q.bind(r.render_id)
                             .bind(r.idx)
                             .bind(r.samples_in_round)
                             .bind(r.samples_total)
                             .bind(r.seconds)
                             .bind(r.error_estimate)
                             .bind(r.error_vs_reference)
                             .bind(or_null(r.buckets_json))
                             .bind(r.created_at)
                             .run();
    if (inserted) {
        // The render's progress is its last recorded round's: kept with the round, not
        // with the checkpoint, which is written less often (see checkpoint_due).
        query("UPDATE renders SET samples_done = MAX(samples_done, ?) WHERE id = ?",
              "record progress of render " + r.render_id)
            .bind(r.samples_total)
            .bind(r.render_id)
            .run();
        return true;
    }

    Query old = query(
        "SELECT samples_in_round, samples_total FROM rounds WHERE render_id = ? AND idx "
        "= ?",
        "add round " + std::to_string(r.idx) + " of render " + r.render_id);
    if (old.bind(r.render_id).bind(r.idx).step() &&
        (old.int64(0) != r.samples_in_round || old.int64(1) != r.samples_total))
        old.refuse("it is already recorded with " + std::to_string(old.int64(0)) +
                   " samples (total " + std::to_string(old.int64(1)) + "), not " +
                   std::to_string(r.samples_in_round) + " (total " +
                   std::to_string(r.samples_total) + ")");
    return false;
}

// One row of kRoundColumns, in that order.
RoundRecord RunStore::round_from_row(Query& q) {
    RoundRecord r;
    r.render_id = q.text(0);
    r.idx = q.int64(1);
    r.samples_in_round = q.int64(2);
    r.samples_total = q.int64(3);
    r.seconds = q.real(4);
    r.error_estimate = q.real(5);
    r.error_vs_reference = q.maybe_real(6);
    r.buckets_json = q.text(7);
    r.created_at = q.int64(8);
    return r;
}

std::vector<RoundRecord> RunStore::rounds(const std::string& render_id) {
    std::lock_guard lock(mutex_);
    static const std::string sql =
        "SELECT " + kRoundColumns + " FROM rounds WHERE render_id = ? ORDER BY idx";
    Query q = query(sql, "read rounds of render " + render_id);
    q.bind(render_id);
    std::vector<RoundRecord> rounds;
    while (q.step()) rounds.push_back(round_from_row(q));
    return rounds;
}

std::optional<RoundRecord> RunStore::last_round(const std::string& render_id) {
    std::lock_guard lock(mutex_);
    static const std::string sql =
        "SELECT " + kRoundColumns +
        " FROM rounds WHERE render_id = ? ORDER BY idx DESC LIMIT 1";
    Query q = query(sql, "read the last round of render " + render_id);
    q.bind(render_id);
    if (!q.step()) return std::nullopt;
    return round_from_row(q);
}

// --- workers

void RunStore::upsert_worker(const std::string& name, int64_t threads, int64_t now_ms) {
    std::lock_guard lock(mutex_);
    query(
        "INSERT INTO workers (name, threads, first_seen, last_seen, samples_traced, "
        "state)"
        " VALUES (?, ?, ?, ?, 0, 'online') ON CONFLICT (name) DO UPDATE SET"
        // 0 threads is "not told": a worker first heard of by a restarted coordinator
        // keeps the count it registered with.
        " threads = CASE WHEN excluded.threads > 0"
        " THEN excluded.threads ELSE threads END,"
        " last_seen = excluded.last_seen, state = 'online'",
        "register worker " + name)
        .bind(name)
        .bind(threads)
        .bind(now_ms)
        .bind(now_ms)
        .run();
}

void RunStore::record_worker_samples(const std::string& name, int64_t samples,
                                     int64_t now_ms) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "UPDATE workers SET samples_traced = samples_traced + ?,"
        " last_seen = MAX(last_seen, ?) WHERE name = ?",
        "record " + std::to_string(samples) + " samples of worker " + name);
    if (samples < 0) q.refuse("a sample count cannot be negative");
    if (q.bind(samples).bind(now_ms).bind(name).run() == 0) q.refuse("no such worker");
}

void RunStore::mark_worker_state(const std::string& name, const std::string& state) {
    std::lock_guard lock(mutex_);
    Query q = query("UPDATE workers SET state = ? WHERE name = ?",
                    "mark worker " + name + " " + state);
    if (q.bind(state).bind(name).run() == 0) q.refuse("no such worker");
}

void RunStore::forget_worker(const std::string& name) {
    std::lock_guard lock(mutex_);
    query("DELETE FROM workers WHERE name = ?", "forget worker " + name).bind(name).run();
}

size_t RunStore::forget_workers_silent_since(int64_t before_ms) {
    std::lock_guard lock(mutex_);
    return size_t(query("DELETE FROM workers WHERE last_seen < ?",
                        "forget workers silent since " + std::to_string(before_ms))
                      .bind(before_ms)
                      .run());
}

std::vector<WorkerRecord> RunStore::workers() {
    std::lock_guard lock(mutex_);
    Query q = query(
        "SELECT name, threads, first_seen, last_seen, samples_traced, state"
        " FROM workers ORDER BY name",
        "list workers");
    std::vector<WorkerRecord> workers;
    while (q.step())
        workers.push_back(WorkerRecord{q.text(0), q.int64(1), q.int64(2), q.int64(3),
                                       q.int64(4), q.text(5)});
    return workers;
}

// --- studies

void RunStore::put_study(const StudyRecord& study) {
    std::lock_guard lock(mutex_);
    query(
        "INSERT INTO studies (id, name, definition_json, created_at) VALUES (?, ?, ?, ?)"
        " ON CONFLICT (id) DO UPDATE SET name = excluded.name,"
        " definition_json = excluded.definition_json",
        "record study " + study.id)
        .bind(study.id)
        .bind(study.name)
        .bind(study.definition_json)
        .bind(study.created_at)
        .run();
}

std::optional<StudyRecord> RunStore::get_study(const std::string& id) {
    std::lock_guard lock(mutex_);
    Query q =
        query("SELECT id, name, definition_json, created_at FROM studies WHERE id = ?",
              "read study " + id);
    if (!q.bind(id).step()) return std::nullopt;
    return StudyRecord{q.text(0), q.text(1), q.text(2), q.int64(3)};
}

void RunStore::link_study_render(const std::string& study_id,
                                 const std::string& render_id) {
    std::lock_guard lock(mutex_);
    query(
        "INSERT INTO study_renders (study_id, render_id) VALUES (?, ?)"
        " ON CONFLICT DO NOTHING",
        "link render " + render_id + " to study " + study_id)
        .bind(study_id)
        .bind(render_id)
        .run();
}

void RunStore::put_study_result(const StudyResult& r) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "INSERT INTO study_results (study_id, render_key, spec_json, origin, remote_id,"
        " render_id, state, samples, rays, seconds, samples_per_second, mean_abs, rmse,"
        " relative_mse, max_bucket, p99_bucket, outcome_json, updated_at,"
        " denoised_mean_abs, denoised_rmse, denoised_relative_mse, mean_bias,"
        " mean_bias_se, denoised_mean_bias, denoised_mean_bias_se)"
        " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?,"
        " ?)"
        " ON CONFLICT (study_id, render_key) DO UPDATE SET spec_json = "
        "excluded.spec_json,"
        " origin = excluded.origin, remote_id = excluded.remote_id,"
        " render_id = excluded.render_id, state = excluded.state,"
        " samples = excluded.samples, rays = excluded.rays, seconds = excluded.seconds,"
        " samples_per_second = excluded.samples_per_second, mean_abs = excluded.mean_abs,"
        " rmse = excluded.rmse, relative_mse = excluded.relative_mse,"
        " max_bucket = excluded.max_bucket, p99_bucket = excluded.p99_bucket,"
        " outcome_json = excluded.outcome_json, updated_at = excluded.updated_at,"
        " denoised_mean_abs = excluded.denoised_mean_abs,"
        " denoised_rmse = excluded.denoised_rmse,"
        " denoised_relative_mse = excluded.denoised_relative_mse,"
        " mean_bias = excluded.mean_bias, mean_bias_se = excluded.mean_bias_se,"
        " denoised_mean_bias = excluded.denoised_mean_bias,"
        " denoised_mean_bias_se = excluded.denoised_mean_bias_se",
        "record render " + r.render_key + " of study " + r.study_id);
    if (r.state != "submitted" && r.state != "done")
        q.refuse("state must be submitted or done, not '" + r.state + "'");
    const auto finite = [](const std::optional<double>& v) {
        return v && std::isfinite(*v) ? v : std::nullopt;
    };
    q.bind(r.study_id)
        .bind(r.render_key)
        .bind(r.spec_json)
        .bind(r.origin)
        .bind(r.remote_id)
        .bind(or_null(r.render_id))
        .bind(r.state)
        .bind(r.samples)
        .bind(r.rays)
        .bind(std::isfinite(r.seconds) ? r.seconds : 0.0)
        .bind(std::isfinite(r.samples_per_second) ? r.samples_per_second : 0.0)
        .bind(finite(r.mean_abs))
        .bind(finite(r.rmse))
        .bind(finite(r.relative_mse))
        .bind(finite(r.max_bucket))
        .bind(finite(r.p99_bucket))
        .bind(or_null(r.outcome_json))
        .bind(r.updated_at)
        .bind(finite(r.denoised_mean_abs))
        .bind(finite(r.denoised_rmse))
        .bind(finite(r.denoised_relative_mse))
        .bind(finite(r.mean_bias))
        .bind(finite(r.mean_bias_se))
        .bind(finite(r.denoised_mean_bias))
        .bind(finite(r.denoised_mean_bias_se))
        .run();
}

std::vector<StudyResult> RunStore::study_results(const std::string& study_id) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "SELECT study_id, render_key, spec_json, origin, remote_id, render_id, state, "
        "samples,"
        " rays, seconds, samples_per_second, mean_abs, rmse, relative_mse, max_bucket,"
        " p99_bucket, outcome_json, updated_at, denoised_mean_abs, denoised_rmse,"
        " denoised_relative_mse, mean_bias, mean_bias_se, denoised_mean_bias,"
        " denoised_mean_bias_se FROM study_results WHERE study_id = ?"
        " ORDER BY rowid",
        "read the renders of study " + study_id);
    q.bind(study_id);
    std::vector<StudyResult> out;
    while (q.step()) {
        StudyResult r;
        r.study_id = q.text(0);
        r.render_key = q.text(1);
        r.spec_json = q.text(2);
        r.origin = q.text(3);
        r.remote_id = q.text(4);
        r.render_id = q.text(5);
        r.state = q.text(6);
        r.samples = q.int64(7);
        r.rays = q.int64(8);
        r.seconds = q.real(9);
        r.samples_per_second = q.real(10);
        r.mean_abs = q.maybe_real(11);
        r.rmse = q.maybe_real(12);
        r.relative_mse = q.maybe_real(13);
        r.max_bucket = q.maybe_real(14);
        r.p99_bucket = q.maybe_real(15);
        r.outcome_json = q.text(16);
        r.updated_at = q.int64(17);
        r.denoised_mean_abs = q.maybe_real(18);
        r.denoised_rmse = q.maybe_real(19);
        r.denoised_relative_mse = q.maybe_real(20);
        r.mean_bias = q.maybe_real(21);
        r.mean_bias_se = q.maybe_real(22);
        r.denoised_mean_bias = q.maybe_real(23);
        r.denoised_mean_bias_se = q.maybe_real(24);
        out.push_back(std::move(r));
    }
    return out;
}

void RunStore::remove_study_result(const std::string& study_id,
                                   const std::string& render_key) {
    std::lock_guard lock(mutex_);
    query("DELETE FROM study_results WHERE study_id = ? AND render_key = ?",
          "forget render " + render_key + " of study " + study_id)
        .bind(study_id)
        .bind(render_key)
        .run();
}

// --- render events

void RunStore::add_render_event(const RenderEventRecord& e, int64_t keep_first,
                                int64_t keep_last) {
    std::lock_guard lock(mutex_);
    const std::string purpose =
        "record event " + std::to_string(e.seq) + " of render " + e.render_id;
    Transaction tx(db_->db, purpose);
    // Again (a retried write, a resumed render): nothing changes.
    query(
        "INSERT INTO render_events (render_id, seq, at_ms, kind, fields_json)"
        " VALUES (?, ?, ?, ?, ?) ON CONFLICT (render_id, seq) DO NOTHING",
        purpose)
        .bind(e.render_id)
        .bind(e.seq)
        .bind(e.at_ms)
        .bind(e.kind)
        .bind(e.fields_json)
        .run();
    // The middle goes: a render of ten thousand rounds keeps its first and last events.
    query("DELETE FROM render_events WHERE render_id = ? AND seq >= ? AND seq <= ?",
          purpose)
        .bind(e.render_id)
        .bind(keep_first)
        .bind(e.seq - keep_last)
        .run();
    tx.commit(purpose);
}

std::vector<RenderEventRecord> RunStore::render_events(const std::string& render_id,
                                                       int64_t after_seq, size_t limit) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "SELECT render_id, seq, at_ms, kind, fields_json FROM render_events"
        " WHERE render_id = ? AND seq > ? ORDER BY seq LIMIT ?",
        "read the events of render " + render_id);
    q.bind(render_id).bind(after_seq).bind(static_cast<int64_t>(limit));
    std::vector<RenderEventRecord> out;
    while (q.step())
        out.push_back({q.text(0), q.int64(1), q.int64(2), q.text(3), q.text(4)});
    return out;
}

std::pair<int64_t, int64_t> RunStore::render_event_span(const std::string& render_id) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "SELECT COUNT(*), COALESCE(MAX(seq), -1) FROM render_events WHERE render_id = ?",
        "count the events of render " + render_id);
    q.bind(render_id);
    if (!q.step()) return {0, -1};
    return {q.int64(0), q.int64(1)};
}

}  // namespace aliquot
