// RunStore's workers: registered, their samples counted, marked and forgotten.
#include "store.h"

#include "store_internal.h"

namespace aliquot {

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

}  // namespace aliquot
