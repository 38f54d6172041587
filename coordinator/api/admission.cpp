#include "admission.h"

#include <algorithm>

namespace aliquot {

Admission::Admission(size_t places, size_t places_per_peer)
    : places_(places), places_per_peer_(std::min(places, places_per_peer)) {}

Admission::Ticket Admission::take(const std::string& peer) {
    {
        std::lock_guard lock(mutex_);
        if (taken_ >= places_) return {};
        // Looked up, not inserted, before the share is checked: a peer refused (a share
        // of 0 refuses every one) leaves no entry behind.
        const auto it = per_peer_.find(peer);
        if ((it == per_peer_.end() ? 0 : it->second) >= places_per_peer_)
            return {nullptr, true};
        ++per_peer_[peer];
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

size_t Admission::peers() const {
    std::lock_guard lock(mutex_);
    return per_peer_.size();
}

}  // namespace aliquot
