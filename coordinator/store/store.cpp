// RunStore on the SQLite C API: one connection, cached prepared statements, numbered
// migrations. The schema and the reasons for the pragmas are in docs/STORE.md. This file
// opens the database (its mode, pragmas and integrity check) and checkpoints the WAL; the
// other store_*.cpp files each define the members of one concern (store_internal.h).
#include "store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <system_error>

#include "store_internal.h"

namespace aliquot {

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

}  // namespace aliquot
