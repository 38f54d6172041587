// Passes over the renders for the leases: the render a lease is issued from, renders in
// LeaseOrder, one whose lock is busy (a merge, or a round's end) passed over at first and
// waited for only when no other render has a job, so one render's round end holds up no
// other render's workers; and the leases whose deadline passed. Each takes each render's
// lock in turn, never two at once, and no other lock (docs/FARM.md, "Locks").
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "render_slot.h"

namespace aliquot {

struct LeaseAsk {
    uint64_t lease_id = 0;  // reserved in the LeaseTable
    std::string worker;     // the identity failures count against
    std::chrono::milliseconds lease_time{};
    const std::set<std::string>* alive = nullptr;  // WorkerRegistry::alive_identities
    FailurePolicy policy;
    size_t cores = 0;  // the alive workers' threads: a round opened here is cut for them
};

struct LeaseScan {
    std::optional<LeaseGrant> grant;
    std::string label;             // the job's "render/job", for the workers list
    std::set<std::string> failed;  // renders a plan made ahead failed (issue)
};

// `slots` in LeaseOrder (Coordinator::slots_by_priority).
LeaseScan scan_for_a_job(const std::vector<SlotPtr>& slots, const LeaseAsk& ask);

// The tick's pass over the renders, each under its lock in turn: the leases past their
// deadline go back to their renders' queues.
struct LeaseSweep {
    std::vector<uint64_t> expired;   // leases past their deadline: ended
    std::set<std::string> finished;  // renders finished: their leases end too
    bool opened_ahead = false;       // a round planned ahead can be leased now
};
LeaseSweep sweep_leases(const std::vector<SlotPtr>& slots,
                        RenderSession::Clock::time_point now);

}  // namespace aliquot
