#include "lease_table.h"

#include "secret.h"

namespace aliquot {

uint64_t LeaseTable::reserve(const std::string& link) {
    std::lock_guard lock(mutex_);
    while (true) {
        uint64_t id = 0;
        random_bytes(&id, sizeof id);
        if (id != 0 && !leases_.count(id)) {
            leases_[id] = {"", link, ""};
            return id;
        }
    }
}

void LeaseTable::grant(uint64_t id, std::string render, std::string label) {
    std::lock_guard lock(mutex_);
    Lease& lease = leases_[id];
    lease.render = std::move(render);
    lease.label = std::move(label);
}

void LeaseTable::end(uint64_t id) {
    std::lock_guard lock(mutex_);
    leases_.erase(id);
}

LeaseTable::Held LeaseTable::held_locked(uint64_t id, const std::string& link) const {
    const auto it = leases_.find(id);
    if (it == leases_.end() || it->second.render.empty()) return {};
    if (it->second.link != link) return {Holding::NotYours, ""};
    return {Holding::Held, it->second.render};
}

LeaseTable::Held LeaseTable::held(uint64_t id, const std::string& link) const {
    std::lock_guard lock(mutex_);
    return held_locked(id, link);
}

LeaseTable::Held LeaseTable::take(uint64_t id, const std::string& link) {
    std::lock_guard lock(mutex_);
    Held out = held_locked(id, link);
    if (out.holding == Holding::Held) leases_.erase(id);
    return out;
}

void LeaseTable::forget_render(const std::string& render) {
    std::lock_guard lock(mutex_);
    std::erase_if(leases_,
                  [&render](const auto& kv) { return kv.second.render == render; });
}

std::unordered_map<std::string, size_t> LeaseTable::leases_by_link() const {
    std::lock_guard lock(mutex_);
    std::unordered_map<std::string, size_t> by_link;
    for (const auto& [id, lease] : leases_) by_link[lease.link] += !lease.render.empty();
    return by_link;
}

std::map<std::string, std::vector<std::string>> LeaseTable::labels_by_link() const {
    std::lock_guard lock(mutex_);
    std::map<std::string, std::vector<std::string>> out;
    for (const auto& [id, lease] : leases_)
        if (!lease.render.empty()) out[lease.link].push_back(lease.label);
    return out;
}

size_t LeaseTable::size() const {
    std::lock_guard lock(mutex_);
    return leases_.size();
}

}  // namespace aliquot
