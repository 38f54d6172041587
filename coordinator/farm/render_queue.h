// RenderQueue: the renders none of whose jobs has been leased yet, in the order the
// coordinator's lease() serves renders (highest priority first, submission order within
// one), so that a queued render's position says which starts next (1: the next).
// Not thread-safe: the Coordinator holds it under its `mutex_`, beside the priorities.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace aliquot {

class RenderQueue {
public:
    // `number`: the render's submission order (RenderSlot::number).
    void add(const std::string& id, int32_t priority, uint64_t number);
    // Takes `id` out (its first job leased, or it was cancelled); whether it was queued.
    bool leave(const std::string& id);
    void set_priority(const std::string& id, int32_t priority);
    // 1 for the render leased next, 2 for the one after, ...; 0 when `id` is not queued.
    uint32_t position(const std::string& id) const;
    size_t size() const { return queued_.size(); }

private:
    struct Entry {
        std::string id;
        int32_t priority = 0;
        uint64_t number = 0;
    };
    static bool before(const Entry& a, const Entry& b);
    std::vector<Entry> queued_;  // kept in lease order
};

}  // namespace aliquot
