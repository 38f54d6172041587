// RunStore's private parts, shared by the files that define its members, a concern a
// file: store.cpp (opening, pragmas, integrity, checkpoints), store_migrations.cpp (the
// schema and its versions), store_scenes.cpp, store_renders.cpp, store_rounds.cpp,
// store_workers.cpp, store_studies.cpp, store_render_events.cpp. Internal to the store
// room: store.h is the interface, and nothing outside coordinator/store/ sees sqlite3.h.
#pragma once

#include <sqlite3.h>

#include <concepts>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "store.h"

namespace aliquot {

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

namespace store_internal {

// Optional text: empty in the records, NULL in the database.
inline std::optional<std::string_view> or_null(const std::string& text) {
    if (text.empty()) return std::nullopt;
    return text;
}

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

}  // namespace store_internal

}  // namespace aliquot
