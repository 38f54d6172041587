// RunStore's scenes: stored once by content hash.
#include "store.h"

#include "store_internal.h"

namespace aliquot {

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

}  // namespace aliquot
