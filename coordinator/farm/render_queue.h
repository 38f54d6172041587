// RenderQueue: the renders none of whose jobs has been leased yet, in the order the
// coordinator's lease() serves renders (LeaseOrder), so that a queued render's position
// says which starts next (1: the next).
// Not thread-safe: the RenderList holds it under its lock, beside the priorities.
#pragma once

#include <cstdint>
#include <set>
#include <string>
#include <unordered_map>

namespace aliquot {

// Whom lease() serves first: the highest priority, and within one the render submitted
// first (`number`, RenderSlot::number; a resumed render keeps its submission order, as
// renders are resumed in it). The one order both lease() and the queue follow.
struct LeaseOrder {
    int32_t priority = 0;
    uint64_t number = 0;
    bool operator<(const LeaseOrder& later) const {
        if (priority != later.priority) return priority > later.priority;
        return number < later.number;
    }
};

class RenderQueue {
public:
    void add(const std::string& id, int32_t priority, uint64_t number);
    // Takes `id` out (its first job leased, or it was cancelled); whether it was queued.
    bool leave(const std::string& id);
    void set_priority(const std::string& id, int32_t priority);
    // 1 for the render leased next, 2 for the one after, ...; 0 when `id` is not queued.
    // Each render's info asks it: after a change the positions are found once, in one
    // pass, and then looked up, so listing thousands of queued renders stays linear.
    uint32_t position(const std::string& id) const;
    size_t size() const { return place_.size(); }

private:
    std::set<std::pair<LeaseOrder, std::string>> queued_;  // in lease order
    std::unordered_map<std::string, LeaseOrder> place_;    // by id
    mutable std::unordered_map<std::string, uint32_t> positions_;
    mutable bool positions_stale_ = false;
};

}  // namespace aliquot
