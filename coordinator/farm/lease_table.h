// LeaseTable: the leases out across renders, each with the render it is of, the worker
// link that holds it (the only one heard about it) and its "render/job" label, so that
// the workers list needs no render's lock. Ids are random: neither an id seen in
// ListWorkers nor the order they are issued in tells another, and a restarted
// coordinator's ids match a pre-restart lease only with probability (leases out) / 2^64.
//
// No lock of its own: the coordinator's (`mutex_`) guards it.
#pragma once

#include <cstdint>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

namespace aliquot {

class LeaseTable {
public:
    struct Lease {
        std::string render;  // render id; empty while the lease is being issued
        std::string link;    // the worker link that leased it
        std::string label;   // "render/job"
    };

    // A fresh id (not 0, not one out), reserved for `link` while a lease is being issued
    // off the lock, so that no other lease takes it meanwhile.
    uint64_t reserve(const std::string& link);
    // The reserved lease `id` was granted: a job of `render`.
    void grant(uint64_t id, std::string render, std::string label);
    const Lease* find(uint64_t id) const;
    void end(uint64_t id) { leases_.erase(id); }
    // Drops the leases in `ended`, and those of renders in `finished` or not `in_memory`
    // (a lease being issued, of no render yet, is not ended).
    template <class InMemory>
    void forget_ended(const std::vector<uint64_t>& ended,
                      const std::set<std::string>& finished, const InMemory& in_memory) {
        for (const uint64_t lease : ended) leases_.erase(lease);
        std::erase_if(leases_, [&](const auto& kv) {
            const std::string& render = kv.second.render;
            return !render.empty() && (finished.count(render) || !in_memory(render));
        });
    }
    // Drops the leases of `render` (it left memory): their results are answered as
    // unknown.
    void forget_render(const std::string& render);
    // The links holding a lease now.
    std::set<std::string> links_holding() const;
    size_t size() const { return leases_.size(); }
    const std::unordered_map<uint64_t, Lease>& all() const { return leases_; }

private:
    std::unordered_map<uint64_t, Lease> leases_;  // by lease id
};

}  // namespace aliquot
