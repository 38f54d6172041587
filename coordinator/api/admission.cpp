#include "admission.h"

#include <algorithm>

namespace aliquot {

Admission::Admission(size_t places, size_t places_per_peer)
    : places_(places), places_per_peer_(std::min(places, places_per_peer)) {}

Admission::Ticket Admission::take(const std::string& peer) {
    {
        std::lock_guard lock(mutex_);
        if (taken_ >= places_) return {};
        const auto it = per_peer_.try_emplace(peer, 0).first;
        if (it->second >= places_per_peer_) return {nullptr, true};
        ++it->second;
        ++taken_;
    }
    // A non-null pointer to nothing: only its deleter matters.
    return {Place(this, [peer](Admission* admission) { admission->give_back(peer); })};
}

void Admission::give_back(const std::string& peer) {
    std::lock_guard lock(mutex_);
    --taken_;
    const auto it = per_peer_.find(peer);
    if (--it->second == 0) per_peer_.erase(it);
}

size_t Admission::taken() const {
    std::lock_guard lock(mutex_);
    return taken_;
}

}  // namespace aliquot
