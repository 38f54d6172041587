// RenderSession's merge path: a result's lease checked and ended (begin_merge), its
// merge counted (end_merge), and a job whose result was refused, or whose merge could
// not keep what it needs, traced again or failing its render (docs/FARM.md, "Locks").
// Apart from render_session.cpp, which plans, issues and ends the rounds.
#include "render_session.h"

#include <string>
#include <string_view>

namespace aliquot {

void RenderSession::give_back(uint64_t lease_id, size_t j) noexcept {
    if (finished() || !lease_to_job_.count(lease_id)) return;
    try {
        requeue(j);  // all or nothing (a deque's push_front)
    } catch (...) {
        return;
    }
    lease_to_job_.erase(lease_id);
}

std::string RenderSession::check_shape(const JobSlot& slot,
                                       const SampleJobResult& result) {
    const SampleJob& job = slot.job;
    if (!(result.rect == job.rect)) return "result rectangle differs from the job's";
    if (result.pixels.size() != job.rect.size())
        return "result has " + std::to_string(result.pixels.size()) +
               " pixels, job has " + std::to_string(job.rect.size());
    return {};
}

CompleteOutcome RenderSession::complete(uint64_t lease_id, const std::string& worker,
                                        const SampleJobResult& result,
                                        const std::set<std::string>& alive,
                                        const FailurePolicy& policy) {
    Merge merge = begin_merge(lease_id, worker, result, nullptr, alive, policy);
    if (merge.outcome) return *merge.outcome;
    add_merge(merge, result);
    return end_merge(merge, alive, policy);
}

CompleteOutcome RenderSession::complete(uint64_t lease_id, const std::string& worker,
                                        SampleJobResult&& result,
                                        const std::set<std::string>& alive,
                                        const FailurePolicy& policy) {
    Merge merge = begin_merge(lease_id, worker, result, &result, alive, policy);
    if (merge.outcome) return *merge.outcome;
    add_merge(merge, result);
    return end_merge(merge, alive, policy);
}

RenderSession::Merge RenderSession::begin_merge(
    uint64_t lease_id, const std::string& worker, const SampleJobResult& result,
    SampleJobResult* movable, const std::set<std::string>& alive,
    const FailurePolicy& policy, const std::string& credit_to) {
    Merge merge;
    if (state_ != RenderState::Running) {
        merge.outcome = {CompleteStatus::Ignored,
                         "render is " + std::string(to_string(state_))};
        return merge;
    }
    const auto it = lease_to_job_.find(lease_id);
    if (it == lease_to_job_.end()) {
        merge.outcome = {CompleteStatus::Ignored,
                         "unknown, expired or already merged lease"};
        return merge;
    }
    JobSlot& slot = jobs_[it->second];
    // Checked before anything else: a result from anyone but the holder neither merges
    // nor ends the lease, and cannot get the holder's job rejected.
    if (slot.worker != worker) {
        merge.outcome = {CompleteStatus::Ignored, "not your lease"};
        return merge;
    }
    const size_t j = it->second;
    const bool ahead = j >= current_jobs_;  // the round after's: held, merged later
    std::string why = check_shape(slot, result);
    if (why.empty() && ahead) {
        // Its sums are checked against the buffers when it merges, at the end of the
        // round out; what it is made of, now.
        try {
            merge.totals = check_as_asked(result, slot.job.counts.data());
        } catch (const MergeError& e) {
            why = e.what();
        }
    }
    // The lease ends last, once nothing is left that can fail: a merge that cannot keep
    // what it needs (no memory) gives its job back instead of losing it. Once its lease
    // has ended, a job merging is no longer issued, even when that lease's time runs out.
    try {
        if (!why.empty()) {
            // Nothing was merged; the job is traced again, preferably by another worker.
            // The outcome first: count_failure queues the job again as its last step, so
            // nothing may throw after it (the give_back below would queue it twice).
            merge.outcome = {CompleteStatus::Rejected, why};
            count_failure(j, worker, "result rejected: " + why, alive, policy);
        } else if (ahead) {
            if (while_keeping) while_keeping(j);
            MergesInFlight::Credit credit{credit_to, merge.totals.samples,
                                          result.wall_seconds};
            merges_.hold(j - current_jobs_,
                         movable ? std::move(*movable) : SampleJobResult(result),
                         std::move(credit));
            merge.outcome = {CompleteStatus::Merged, {}};
            merge.held = true;
        } else {
            if (while_keeping) while_keeping(j);
            merges_.begin_add(j);
            merge.job = j;
            merge.counts =
                slot.job.counts.data();  // cut at its lease, kept to the round's end
        }
    } catch (...) {
        give_back(lease_id, j);
        throw;
    }
    lease_to_job_.erase(lease_id);
    return merge;
}

CompleteOutcome RenderSession::end_merge(Merge& merge, const std::set<std::string>& alive,
                                         const FailurePolicy& policy) {
    merges_.count(merge.job);
    if (!merge.added) {
        // The render ended meanwhile: its job no longer matters.
        if (state_ != RenderState::Running)
            return {CompleteStatus::Ignored,
                    "render is " + std::string(to_string(state_))};
        try {
            count_failure(merge.job, jobs_[merge.job].worker,
                          "result rejected: " + merge.refused, alive, policy);
        } catch (...) {
            // No lease, no add in flight, not queued (count_failure's last step): queued
            // here, or the render fails, or nothing would issue it and the round would
            // never end.
            requeue_or_fail(merge.job);
            throw;
        }
        return {CompleteStatus::Rejected, merge.refused};
    }
    // Added before the render ended (its end waited for the add): in its image.
    if (state_ != RenderState::Running) return {CompleteStatus::Merged, {}};
    if (++merged_jobs_ == current_jobs_) end_rounds(alive, policy);
    return {CompleteStatus::Merged, {}};
}

bool RenderSession::fail_job(uint64_t lease_id, const std::string& worker,
                             const std::string& reason,
                             const std::set<std::string>& alive,
                             const FailurePolicy& policy) {
    const auto it = lease_to_job_.find(lease_id);
    if (it == lease_to_job_.end() || jobs_[it->second].worker != worker) return false;
    const size_t j = it->second;
    lease_to_job_.erase(it);
    try {
        count_failure(j, worker, reason, alive, policy);
    } catch (...) {
        requeue_or_fail(j);  // in no queue and under no lease: count_failure's last step
        throw;
    }
    return true;
}

void RenderSession::count_failure(size_t j, const std::string& worker,
                                  const std::string& reason,
                                  const std::set<std::string>& alive,
                                  const FailurePolicy& policy) {
    if (while_counting_failure) while_counting_failure(j);
    JobSlot& slot = jobs_[j];
    const std::string why =
        failures_.count(slot.failures, slot.job.rect, worker, reason, alive, policy);
    if (!why.empty()) return fail(why);
    // Back to the front: the next worker that may take it does.
    requeue(j);
}

void RenderSession::count_refusal(size_t j, const std::string& why,
                                  const std::set<std::string>& alive,
                                  const FailurePolicy& policy) noexcept {
    try {
        count_failure(j, jobs_[j].worker, "result rejected: " + why, alive, policy);
    } catch (...) {
        requeue_or_fail(j);  // count_failure queues the job as its last step
    }
}

void RenderSession::requeue_or_fail(size_t j) noexcept {
    if (finished()) return;
    try {
        return requeue(j);  // all or nothing (a deque's push_front)
    } catch (...) {
    }
    try {
        return fail("out of memory: a job could not be queued again");
    } catch (...) {
    }
    fail_out_of_memory();
}

void RenderSession::fail_in_catch(const char* doing) noexcept {
    try {
        // The round a plan is for is the next; the round an end is of, the one out.
        const bool plan = std::string_view(doing) == "plan";
        std::string why = "cannot ";
        why += doing;
        why += " round " + std::to_string(round_index_ + (plan ? 1 : 0)) + ": ";
        try {
            throw;
        } catch (const std::exception& e) {
            why += e.what();
        } catch (...) {
            why += "unknown error";
        }
        return fail(why);
    } catch (...) {
    }
    fail_out_of_memory();
}

void RenderSession::fail_out_of_memory() noexcept {
    if (finished()) return;    // its end threw (on_finished): it has failed all the same
    error_ = "out of memory";  // held in std::string's own buffer: takes no memory
    try {
        finish(RenderState::Failed);
    } catch (...) {
    }
}

}  // namespace aliquot
