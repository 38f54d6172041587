#include "lease_table.h"

#include "secret.h"

namespace aliquot {

uint64_t LeaseTable::reserve(const std::string& link) {
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
    Lease& lease = leases_[id];
    lease.render = std::move(render);
    lease.label = std::move(label);
}

const LeaseTable::Lease* LeaseTable::find(uint64_t id) const {
    const auto it = leases_.find(id);
    return it == leases_.end() ? nullptr : &it->second;
}

void LeaseTable::forget_render(const std::string& render) {
    std::erase_if(leases_,
                  [&render](const auto& kv) { return kv.second.render == render; });
}

std::set<std::string> LeaseTable::links_holding() const {
    std::set<std::string> holding;
    for (const auto& [id, lease] : leases_) holding.insert(lease.link);
    return holding;
}

}  // namespace aliquot
