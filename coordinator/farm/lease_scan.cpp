#include "lease_scan.h"

#include <mutex>

namespace aliquot {

namespace {

// Under the slot's lock.
void try_issue(RenderSlot& slot, const LeaseAsk& ask, LeaseScan& out) {
    RenderSession& s = *slot.session;
    if (s.state() != RenderState::Running || !s.has_pending()) return;
    s.set_worker_cores(ask.cores);
    std::optional<SampleJob> job =
        s.issue(ask.lease_id, ask.worker, RenderSession::Clock::now() + ask.lease_time,
                *ask.alive, ask.policy);
    if (s.state() == RenderState::Failed) out.failed.insert(s.id());
    if (!job) return;
    out.label = s.lease_label(ask.lease_id);
    out.grant =
        LeaseGrant{ask.lease_id,    s.id(),
                   s.scene_hash(),  {s.spec().width, s.spec().height, s.spec().seed},
                   std::move(*job), uint32_t(ask.lease_time.count())};
}

}  // namespace

LeaseScan scan_for_a_job(const std::vector<SlotPtr>& slots, const LeaseAsk& ask) {
    LeaseScan out;
    std::vector<RenderSlot*> busy;
    for (const SlotPtr& slot : slots) {
        std::unique_lock render(slot->mutex, std::try_to_lock);
        if (!render.owns_lock()) {
            busy.push_back(slot.get());
            continue;
        }
        try_issue(*slot, ask, out);
        if (out.grant) return out;
    }
    for (size_t i = 0; !out.grant && i < busy.size(); ++i) {
        std::lock_guard render(busy[i]->mutex);
        try_issue(*busy[i], ask, out);
    }
    return out;
}

LeaseSweep sweep_leases(const std::vector<SlotPtr>& slots,
                        RenderSession::Clock::time_point now) {
    LeaseSweep out;
    for (const SlotPtr& slot : slots) {
        std::lock_guard render(slot->mutex);
        RenderSession& s = *slot->session;
        if (s.finished()) {
            out.finished.insert(s.id());
            continue;
        }
        for (const uint64_t lease : s.expire(now)) out.expired.push_back(lease);
        out.opened_ahead = s.announce_next_round() || out.opened_ahead;
    }
    return out;
}

}  // namespace aliquot
