#include "render_queue.h"

namespace aliquot {

void RenderQueue::add(const std::string& id, int32_t priority, uint64_t number) {
    leave(id);
    const LeaseOrder order{priority, number};
    place_[id] = order;
    queued_.emplace(order, id);
    positions_stale_ = true;
}

bool RenderQueue::leave(const std::string& id) {
    const auto it = place_.find(id);
    if (it == place_.end()) return false;
    queued_.erase({it->second, id});
    place_.erase(it);
    positions_stale_ = true;
    return true;
}

void RenderQueue::set_priority(const std::string& id, int32_t priority) {
    const auto it = place_.find(id);
    if (it != place_.end()) add(id, priority, it->second.number);
}

uint32_t RenderQueue::position(const std::string& id) const {
    if (positions_stale_) {
        positions_.clear();
        uint32_t n = 0;
        for (const auto& [order, queued] : queued_) positions_[queued] = ++n;
        positions_stale_ = false;
    }
    const auto it = positions_.find(id);
    return it == positions_.end() ? 0 : it->second;
}

}  // namespace aliquot
