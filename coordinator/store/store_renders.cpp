// RunStore's renders: created, moved between states, given progress and priority,
// finished, listed, counted and deleted.
#include "store.h"

#include "store_internal.h"

namespace aliquot {

using store_internal::or_null;
using store_internal::Transaction;

namespace {

const std::string kRenderColumns =
    "id, scene_hash, spec_json, state, error, created_at, started_at, finished_at, "
    "samples_planned, samples_done, strategy_state_json, outcome_json, reference_path, "
    "priority";

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
    // A state that is not an end never overwrites one: the records are written in order,
    // but a render's start is noted after its lock is let go, so a cancel in that gap
    // queues its end first, and a late "running" would have a restart resume a render its
    // client cancelled.
    Query q = query(
        "UPDATE renders SET state = ?, error = ?,"
        " started_at = CASE WHEN ? THEN COALESCE(started_at, ?) ELSE started_at END,"
        " finished_at = ? WHERE id = ?"
        " AND NOT (? AND state IN ('done', 'cancelled', 'failed'))",
        "set render " + id + " " + std::string(to_string(state)));
    q.bind(to_string(state))
        .bind(or_null(error))
        .bind(state == RenderState::Running)
        .bind(now_ms);
    if (is_terminal(state))
        q.bind(now_ms);
    else
        q.bind(std::nullopt);
    if (q.bind(id).bind(!is_terminal(state)).run() > 0) return;
    Query known = query("SELECT 1 FROM renders WHERE id = ?", "look for render " + id);
    if (!known.bind(id).step()) q.refuse("no such render");
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

}  // namespace aliquot
