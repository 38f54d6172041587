// RunStore's render events (coordinator/farm/render_events.h): each render keeps its
// first and last few.
#include "store.h"

#include "store_internal.h"

namespace aliquot {

using store_internal::Transaction;

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
