// RunStore's rounds: a render's progress, one row a round, recorded again as a no-op.
#include "store.h"

#include <cmath>

#include "store_internal.h"

namespace aliquot {

using store_internal::or_null;

namespace {

const std::string kRoundColumns =
    "render_id, idx, samples_in_round, samples_total, seconds, error_estimate, "
    "error_vs_reference, buckets_json, created_at, mean_bias, mean_bias_se";

}  // namespace

bool RunStore::add_round(const RoundRecord& r) {
    std::lock_guard lock(mutex_);
    static const std::string sql = "INSERT INTO rounds (" + kRoundColumns +
                                   ") VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)"
                                   " ON CONFLICT (render_id, idx) DO NOTHING";
    Query q =
        query(sql, "add round " + std::to_string(r.idx) + " of render " + r.render_id);
    // SQLite stores NaN as NULL; refuse it here with a message that says so.
    if (!std::isfinite(r.seconds)) q.refuse("its seconds are not finite");
    if (!std::isfinite(r.error_estimate)) q.refuse("its error estimate is not finite");
    if (r.error_vs_reference && !std::isfinite(*r.error_vs_reference))
        q.refuse("its error against the reference is not finite");
    if ((r.mean_bias && !std::isfinite(*r.mean_bias)) ||
        (r.mean_bias_se && !std::isfinite(*r.mean_bias_se)))
        q.refuse("its mean bias is not finite");
    const int inserted = q.bind(r.render_id)
                             .bind(r.idx)
                             .bind(r.samples_in_round)
                             .bind(r.samples_total)
                             .bind(r.seconds)
                             .bind(r.error_estimate)
                             .bind(r.error_vs_reference)
                             .bind(or_null(r.buckets_json))
                             .bind(r.created_at)
                             .bind(r.mean_bias)
                             .bind(r.mean_bias_se)
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
    r.mean_bias = q.maybe_real(9);
    r.mean_bias_se = q.maybe_real(10);
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

}  // namespace aliquot
