// The render a lease is issued from: renders in LeaseOrder, one whose lock is busy (a
// merge, or a round's end) passed over at first and waited for only when no other render
// has a job, so one render's round end holds up no other render's workers. Takes each
// render's lock in turn, never two at once, and no other lock (docs/FARM.md, "Locks").
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

}  // namespace aliquot
