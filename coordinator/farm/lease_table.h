// LeaseTable: the leases out across renders, each with the render it is of, the worker
// link that holds it (the only one heard about it) and its "render/job" label, so that
// the workers list needs no render's lock. Ids are random: neither an id seen in
// ListWorkers nor the order they are issued in tells another, and a restarted
// coordinator's ids match a pre-restart lease only with probability (leases out) / 2^64.
//
// Its own lock, a leaf of the farm's lock order (docs/FARM.md, "Locks"): nothing else is
// taken while it is held, and every method takes it, so a lease is taken, checked and
// ended in one step however many workers call at once.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

namespace aliquot {

class LeaseTable {
public:
    // A fresh id (not 0, not one out), reserved for `link` while a lease is being issued
    // off the lock, so that no other lease takes it meanwhile.
    uint64_t reserve(const std::string& link);
    // The reserved lease `id` was granted: a job of `render`.
    void grant(uint64_t id, std::string render, std::string label);
    void end(uint64_t id);

    // What a worker's word on a lease finds: a lease of another link stays with its
    // holder (`NotYours`), whose own result still counts.
    enum class Holding { Unknown, NotYours, Held };
    struct Held {
        Holding holding = Holding::Unknown;
        std::string render;  // when Held
    };
    // The render of the granted lease `id` if `link` holds it.
    Held held(uint64_t id, const std::string& link) const;
    // The same, and a lease held ends here: of two calls with one lease, one takes it.
    Held take(uint64_t id, const std::string& link);

    // Drops the leases in `ended`, and those of renders in `finished` or not `in_memory`
    // (a lease being issued, of no render yet, is not ended). `in_memory` is called
    // under this table's lock: it may read what its caller holds, and take no lock.
    template <class InMemory>
    void forget_ended(const std::vector<uint64_t>& ended,
                      const std::set<std::string>& finished, const InMemory& in_memory) {
        std::lock_guard lock(mutex_);
        for (const uint64_t lease : ended) leases_.erase(lease);
        std::erase_if(leases_, [&](const auto& kv) {
            const std::string& render = kv.second.render;
            return !render.empty() && (finished.count(render) || !in_memory(render));
        });
    }
    // Drops the leases of `render` (it left memory): their results are answered as
    // unknown.
    void forget_render(const std::string& render);
    // The links holding a lease now, each with how many of its leases are granted (a job
    // of a render; a lease only reserved, being issued, is held but not yet counted):
    // what WorkerRegistry counts a worker's cores by, in one pass.
    std::unordered_map<std::string, size_t> leases_by_link() const;
    // The granted leases' labels by the link holding them (the workers list).
    std::map<std::string, std::vector<std::string>> labels_by_link() const;
    size_t size() const;

private:
    struct Lease {
        std::string render;  // render id; empty while the lease is being issued
        std::string link;    // the worker link that leased it
        std::string label;   // "render/job"
    };
    Held held_locked(uint64_t id, const std::string& link) const;

    mutable std::mutex mutex_;
    std::unordered_map<uint64_t, Lease> leases_;  // by lease id
};

}  // namespace aliquot
