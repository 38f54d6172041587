// RenderList: the renders the Coordinator holds in memory, by id and in submission order,
// their priorities, the queue of those none of whose jobs is leased yet, and the change
// counter that waiting calls (lease polls, event streams, a removal) wait on; all under
// the one coordinator-wide lock, which this class alone takes. It is held for look-ups
// and bookkeeping only: a render's own work happens under its RenderSlot::mutex, which
// is never taken under this lock (docs/FARM.md, "Locks", has the order).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "lease_table.h"
#include "render_queue.h"
#include "render_slot.h"

namespace aliquot {

class RenderList {
public:
    // Adds a render. `start` wires and starts its slot under this list's lock, before
    // anyone can find it, so that a render leaving memory meanwhile (its end written at
    // once) cannot miss it; it returns whether the render waits in the queue until its
    // first lease. It takes no lock but the leaves (docs/FARM.md).
    void add(std::unique_ptr<RenderSession> session,
             const std::function<bool(RenderSlot&)>& start);
    // Drops render `id` when it has finished, calling `release` on it first under this
    // list's lock (what is kept per render: memory, scene, events, leases); whether it
    // was dropped. A call that found the slot before keeps it until it is done.
    bool drop_finished(const std::string& id,
                       const std::function<void(RenderSession&)>& release);

    // The render `id`, or null.
    SlotPtr find(const std::string& id);
    bool contains(const std::string& id) { return find(id) != nullptr; }
    // The render `id` with its priority and place in the queue (0: not queued).
    struct Place {
        SlotPtr slot;
        int32_t priority = 0;
        uint32_t queued_at = 0;
    };
    Place place_of(const std::string& id);
    // Every render in submission order, each with whether it waits in the queue.
    std::vector<std::pair<SlotPtr, bool>> in_order_with_queued();
    std::vector<SlotPtr> in_order();
    // The ids of the newest `limit` renders, newest first.
    std::vector<std::string> newest_ids(size_t limit);
    size_t size();

    // What lease() scans: the renders in LeaseOrder (render_queue.h) and the change
    // counter they were read at; nullopt once stopping.
    struct Snapshot {
        uint64_t seen = 0;
        std::vector<SlotPtr> slots;
    };
    std::optional<Snapshot> by_priority();
    // Render `id` had its first job leased: out of the queue; whether it was in it.
    bool leased(const std::string& id);
    void set_priority(SlotPtr slot, int32_t priority);
    // Render `id` was cancelled: its leases ended with it, and it leaves the queue.
    void cancelled(const std::string& id, LeaseTable& leases);

    // Something a waiting call may look for changed.
    void note_change();
    // Drops the leases that ended (`ended`) and those of renders finished or gone (the
    // table asks this list which renders are in memory, under both locks), and notes a
    // change when `changed`.
    void note_ended(LeaseTable& leases, const std::vector<uint64_t>& ended,
                    const std::set<std::string>& finished, bool changed = true);
    // Waits until the counter passes `seen` (or stopping), up to `deadline`; whether it
    // did.
    bool wait_for_work(uint64_t seen, std::chrono::steady_clock::time_point deadline);
    // Waits up to `timeout` for the counter to pass `seen`; returns it.
    uint64_t wait_for_change(uint64_t seen, std::chrono::milliseconds timeout);
    // Waits while render `id` is here, until stopping, `give_up` says so (asked under
    // this lock, it must take only leaves) or `deadline`; whether it is still here.
    bool wait_until_gone(const std::string& id,
                         std::chrono::steady_clock::time_point deadline,
                         const std::function<bool()>& give_up);
    // Wakes every waiting call; by_priority answers nullopt from now on.
    void stop();

private:
    SlotPtr slot_of(const std::string& id) const;  // under mutex_
    void changed();                                // under mutex_
    // LeaseTable::forget_ended, asking this list which renders are in memory; under
    // mutex_.
    void forget_leases(LeaseTable& leases, const std::vector<uint64_t>& ended,
                       const std::set<std::string>& finished) const;

    std::mutex mutex_;
    std::condition_variable work_ready_;  // lease polls
    std::condition_variable progress_;    // wait_for_change, wait_until_gone
    uint64_t version_ = 0;
    uint64_t submissions_ = 0;                 // renders added so far: RenderSlot::number
    std::map<std::string, SlotPtr> sessions_;  // by id
    std::vector<std::string> order_;           // submission order
    RenderQueue queue_;                        // renders no job of which was leased yet
    bool stopping_ = false;
};

}  // namespace aliquot
