#include "render_queue.h"

#include <algorithm>

namespace aliquot {

bool RenderQueue::before(const Entry& a, const Entry& b) {
    // As Coordinator::slots_by_priority orders renders for lease().
    if (a.priority != b.priority) return a.priority > b.priority;
    return a.number < b.number;
}

void RenderQueue::add(const std::string& id, int32_t priority, uint64_t number) {
    leave(id);
    Entry e{id, priority, number};
    queued_.insert(std::upper_bound(queued_.begin(), queued_.end(), e, before),
                   std::move(e));
}

bool RenderQueue::leave(const std::string& id) {
    const auto it = std::find_if(queued_.begin(), queued_.end(),
                                 [&](const Entry& e) { return e.id == id; });
    if (it == queued_.end()) return false;
    queued_.erase(it);
    return true;
}

void RenderQueue::set_priority(const std::string& id, int32_t priority) {
    const auto it = std::find_if(queued_.begin(), queued_.end(),
                                 [&](const Entry& e) { return e.id == id; });
    if (it == queued_.end()) return;
    const uint64_t number = it->number;
    queued_.erase(it);
    add(id, priority, number);
}

uint32_t RenderQueue::position(const std::string& id) const {
    for (size_t i = 0; i < queued_.size(); ++i)
        if (queued_[i].id == id) return uint32_t(i + 1);
    return 0;
}

}  // namespace aliquot
