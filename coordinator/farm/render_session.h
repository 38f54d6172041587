// RenderSession: one render's life on the coordinator. It owns the render's buffers and
// strategy, cuts each round into sample jobs, hands them out under leases and merges what
// comes back. No I/O, and no locking but the merges' own: the Coordinator serialises
// calls (the render's lock) and persists; a merge's add runs off that lock (add_merge).
#pragma once

#include <chrono>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "accumulator.h"
#include "aux_sums.h"
#include "job_failures.h"
#include "lease.h"
#include "merges_in_flight.h"
#include "render_spec.h"
#include "render_state.h"
#include "round_cutter.h"
#include "strategy.h"

namespace aliquot {

struct RoundSummary {
    uint32_t index = 0;
    uint64_t samples_in_round = 0;
    uint64_t samples_total = 0;
    double seconds = 0;              // wall time since the render started
    double error_estimate = -1;      // see error_estimate.h
    double error_vs_reference = -1;  // the seed's E against the reference, if any
    // The image's mean bias against the reference and its standard error, fractions
    // (error_metric.h): E falls as a biased method converges, its image still too dark.
    // Absent without a reference, and where there is none (a black reference, an image
    // holding NaN or inf, a single block for the SE).
    std::optional<double> mean_bias, mean_bias_se;
};

class RenderSession {
public:
    using Clock = std::chrono::steady_clock;

    RenderSession(std::string id, RenderSpec spec, int64_t created_ms);
    // With `strategy` instead of the one the spec names (tests).
    RenderSession(std::string id, RenderSpec spec, int64_t created_ms,
                  std::unique_ptr<Strategy> strategy);

    // Continues from a checkpoint taken at a round boundary: the merged buffers and the
    // strategy's state then, with the round it had planned ahead, if any
    // (Checkpoint::planned_round). Call before start().
    // With spec().aux, `aux` holds the checkpoint's first-hit sums (a checkpoint
    // without them, or with them for a render that keeps none, is refused).
    void restore(Accumulator merged, const nlohmann::json& strategy_state,
                 uint32_t rounds_done, double seconds_before,
                 std::vector<uint32_t> planned_round = {}, AuxSums aux = {});
    // Plans the first (or next, after restore) round; the render is then Running or Done.
    void start();

    // Hands out the next pending job `worker` may take under `lease_id`, or nullopt when
    // none is. `alive` are the workers that could take a job now (the caller's own
    // name may be among them): a job that failed on `worker` goes to one of them instead,
    // and a blocklisted `worker` gets nothing while one of them is not. Empty: no choice.
    std::optional<SampleJob> issue(uint64_t lease_id, const std::string& worker,
                                   Clock::time_point deadline,
                                   const std::set<std::string>& alive = {},
                                   const FailurePolicy& policy = {});
    // Merges `worker`'s result for its lease. A lease another worker holds is refused
    // ("not your lease") and stays with its holder; so do renew, abandon and fail_job.
    // A result that does not fit its job is rejected and counts as a failure, as
    // fail_job's do: a worker that keeps returning one cannot keep a render going round.
    // begin_merge, add_merge and end_merge in one (a caller that serialises every call).
    CompleteOutcome complete(uint64_t lease_id, const std::string& worker,
                             const SampleJobResult& result,
                             const std::set<std::string>& alive = {},
                             const FailurePolicy& policy = {});
    // The same, a result held for the round ahead taken by move.
    CompleteOutcome complete(uint64_t lease_id, const std::string& worker,
                             SampleJobResult&& result,
                             const std::set<std::string>& alive = {},
                             const FailurePolicy& policy = {});

    // A merge in three steps, so that merges of one round's jobs, which cover disjoint
    // pixels, add their sums at once: begin_merge under the render's lock (the lease
    // checked and ended, the job marked merging), add_merge off it, end_merge under it
    // again (the merge counted, the round ended). A round ends when its last job's
    // end_merge counts it, so no add of its is in flight then; results of the round
    // ahead are held (moved from `movable` when given, copied otherwise) in begin_merge
    // and added at the round end, under the lock. Readers of the buffers' pixels
    // (image, wait_for_adds) and the render's end wait for adds in flight.
    using Merge = MergesInFlight::Merge;
    // A held result's samples count for `credit_to` when it merges (on_held_merged).
    Merge begin_merge(uint64_t lease_id, const std::string& worker,
                      const SampleJobResult& result, SampleJobResult* movable,
                      const std::set<std::string>& alive = {},
                      const FailurePolicy& policy = {},
                      const std::string& credit_to = {});
    // Checks `result` against its job and the buffers, then adds it, or refuses it
    // whole (MergesInFlight::add). Takes no lock but the adds' own; never throws.
    void add_merge(Merge& merge, const SampleJobResult& result) {
        merges_.add(merge, result, merged_, aux_, while_adding);
    }
    CompleteOutcome end_merge(Merge& merge, const std::set<std::string>& alive = {},
                              const FailurePolicy& policy = {});
    // Waits (under the render's lock) until no add is in flight: the buffers' pixels
    // are then what the merges counted so far made them.
    void wait_for_adds() const { merges_.wait_for_adds(); }
    // Tests: called in add_merge between its check and its add, off the render's lock.
    std::function<void(size_t job)> while_adding;
    // Tests: called in begin_merge where a merge keeps what it needs (its add recorded
    // in flight, a held result's copy), before the lease ends; a test throws
    // std::bad_alloc there.
    std::function<void(size_t job)> while_keeping;
    // Tests: called as a job's failure starts to be counted (a refused result's), before
    // the job is queued again; a test throws std::bad_alloc there.
    std::function<void(size_t job)> while_counting_failure;
    // Tests: called as a job goes back to its queue (requeue), before it does; a test
    // throws std::bad_alloc there.
    std::function<void(size_t job)> while_requeueing;
    // Tests: called as each held result of the round ahead is added when its round
    // comes, between its check and its add, under the render's lock.
    std::function<void(size_t job)> while_adding_held;
    bool renew(uint64_t lease_id, const std::string& worker, Clock::time_point deadline);
    bool abandon(uint64_t lease_id, const std::string& worker);
    // `worker` could not trace its lease, for `reason`: the failure counts against the
    // job and the worker, and the job goes back to the queue, or the render fails with
    // the reason when the policy says so. False (nothing changes) when the lease is not
    // the worker's.
    bool fail_job(uint64_t lease_id, const std::string& worker, const std::string& reason,
                  const std::set<std::string>& alive, const FailurePolicy& policy);
    // The farm's live worker cores: the rounds cut from now on get at least two jobs a
    // core (round_cutter.h, min_jobs_for_cores). Which job a pixel's samples travel in
    // never changes a bit of the image.
    void set_worker_cores(size_t cores) { min_jobs_ = min_jobs_for_cores(cores); }
    // Whether `lease_id` is out now (issued, not yet merged, expired or given back).
    bool holds(uint64_t lease_id) const { return lease_to_job_.count(lease_id) > 0; }
    // Failures of `worker` on this render's jobs.
    uint32_t failures_of(const std::string& worker) const { return failures_.of(worker); }
    // Returns leases whose deadline passed to the pending queue; which they were.
    std::vector<uint64_t> expire(Clock::time_point now);
    void cancel();
    void fail(const std::string& message);

    // Whether a job may be there to issue: one pending, or a round planned ahead that
    // may open (issue says for certain).
    bool has_pending() const {
        return !pending_.empty() || !next_pending_.empty() || plan_coming();
    }
    // True once a round, when the next issue would look at a plan made ahead that is
    // now done (every job of the round out leased, the plan's work ended). Nothing else
    // tells workers waiting for a job that one may be there: the Coordinator's tick asks,
    // and wakes them.
    bool announce_next_round() {
        if (announced_ || state_ != RenderState::Running || !pending_.empty() ||
            next_spp_ || next_tried_ || !work_ahead_.valid() ||
            work_ahead_.wait_for(std::chrono::seconds(0)) != std::future_status::ready)
            return false;
        return announced_ = true;
    }
    bool finished() const { return is_terminal(state_); }
    // "render/job" of the lease `lease_id` out now, empty when it is not: what the
    // workers list shows it as (kept with the lease, so that list takes no render lock).
    std::string lease_label(uint64_t lease_id) const;

    const std::string& id() const { return id_; }
    const RenderSpec& spec() const { return spec_; }
    const std::string& scene_hash() const { return scene_hash_; }
    RenderState state() const { return state_; }
    const std::string& error() const { return error_; }
    const Accumulator& merged() const { return merged_; }
    // The first-hit sums of a render with spec().aux; kept() is false for any other.
    const AuxSums& aux() const { return aux_; }
    // The merged image as written and fetched: with `aovs` its layers, and always the
    // spec's attributes (render_attributes.h).
    Image image(bool aovs) const;
    const Strategy& strategy() const { return *strategy_; }
    uint32_t rounds_done() const { return rounds_done_; }
    // Whether the round out was opened ahead: its jobs were leased before the round
    // before it ended, so that round's end held up none of its workers.
    bool round_opened_ahead() const { return opened_ahead_; }
    // Seconds the render had no job to lease because the round after the one out was
    // still being planned ahead (every job of the round out leased, the plan not made):
    // the workers that asked then waited on the coordinator, as through a round end that
    // is waited through (which is not counted here). bench/farm_scale.
    double plan_wait_seconds() const { return plan_wait_seconds_; }
    uint64_t samples_planned() const { return strategy_->planned_samples(); }
    double seconds() const;
    double error_estimate() const { return last_round_.error_estimate; }
    double error_vs_reference() const { return last_round_.error_vs_reference; }
    const RoundSummary& last_round() const { return last_round_; }
    int64_t created_ms() const { return created_ms_; }

    // Called after a round is fully merged, before the next is planned: the moment a
    // checkpoint captures (the strategy's state still describes the merged buffers).
    std::function<void(RenderSession&, const RoundSummary&)> on_round;
    // Called, under the render's lock, as a held result of the round ahead merges at its
    // round's start: what it adds counts as merged from then (begin_merge's outcome said
    // Merged, but one refused then counts for no one, as any refused result). Must not
    // throw.
    std::function<void(const MergesInFlight::Credit&)> on_held_merged;
    // Called once when the render reaches Done, Cancelled or Failed.
    std::function<void(RenderSession&)> on_finished;

private:
    struct JobSlot {
        // Pending, leased or merged is where its index is: pending_, lease_to_job_,
        // neither.
        SampleJob job;
        std::string worker;
        Clock::time_point deadline;
        JobFailures::OfJob failures;
        bool cut = false;  // job holds its counts and first samples, not only its rect
    };

    // Ends the round out when its last job merged, and the round after it too when that
    // one, opened ahead, has merged whole meanwhile.
    void end_rounds(const std::set<std::string>& alive, const FailurePolicy& policy);
    // `alive` and `policy` judge a held result that fails to merge (complete's).
    void plan_next_round(const std::set<std::string>& alive = {},
                         const FailurePolicy& policy = {});
    // Opens the round after the one out when the strategy has planned it ahead and every
    // job of the round out is leased: its jobs are then leased too.
    void open_next_round();
    // A job no longer leased and not done goes back to the front of its round's queue.
    void requeue(size_t j);
    // A merge of lease `lease_id` (job `j`) failed to begin (no memory): its job goes
    // back to its queue now, or, should that fail too, when its lease expires.
    void give_back(uint64_t lease_id, size_t j) noexcept;
    // The round out's jobs not merged yet, for cutting the round after's.
    std::vector<const SampleJob*> unmerged_jobs() const;
    // Waits for the strategy's work ahead (take_work_ahead) to end; rethrows what it
    // threw.
    void finish_work_ahead();
    // After a round end (or at start): the strategy's long plan made on work_ahead_'s
    // thread, off the caller's lock (Strategy::take_round_end), or the next round planned
    // here. While that plan runs no round is out: issue finds nothing, and once it has
    // ended the next issue hands the round out (open_round_end_plan).
    void begin_next_round(const std::set<std::string>& alive = {},
                          const FailurePolicy& policy = {});
    // True when no round end's plan runs: none did, or it has ended and its round is
    // out; false while it runs, or when its end ended the render.
    bool open_round_end_plan(const std::set<std::string>& alive,
                             const FailurePolicy& policy);
    void finish(RenderState state);
    // Called in a catch block: fails the render with "cannot `doing` round n: " and the
    // exception's reason, or, when even that cannot be said (no memory), with "out of
    // memory". Never throws.
    void fail_in_catch(const char* doing) noexcept;
    // After a fail() that threw before the render ended (no memory for its reason):
    // fails it with "out of memory", which takes none. Never throws.
    void fail_out_of_memory() noexcept;
    // Whether `result` is of its job's rectangle and size (its pixels are add_merge's).
    static std::string check_shape(const JobSlot& slot, const SampleJobResult& result);
    // Counts a failure of job `j` (no longer leased) against it and `worker`: back to the
    // queue, or the render fails with `reason` when the policy says so.
    void count_failure(size_t j, const std::string& worker, const std::string& reason,
                       const std::set<std::string>& alive, const FailurePolicy& policy);
    // Counts the refusal of job `j`'s result (count_failure); when that throws (no
    // memory), requeue_or_fail. Never throws: the held results after it still merge.
    void count_refusal(size_t j, const std::string& why,
                       const std::set<std::string>& alive,
                       const FailurePolicy& policy) noexcept;
    // Job `j`, in no queue and under no lease, goes back to its queue; when even that
    // fails, the render fails: a job in no queue would hold its round open for good.
    void requeue_or_fail(size_t j) noexcept;

    std::string id_;
    RenderSpec spec_;
    std::string scene_hash_;  // of spec_.scene_json; every lease carries it
    int64_t created_ms_;
    std::unique_ptr<Strategy> strategy_;
    Accumulator merged_;
    AuxSums aux_;  // merged with merged_, by merge_with_aux
    RenderState state_ = RenderState::Queued;
    std::string error_;

    uint32_t round_index_ = 0;
    uint64_t round_samples_ = 0;
    size_t min_jobs_ = kMinJobsPerRound;  // a round's jobs at least (set_worker_cores)
    // The round out: its jobs are cut from it as they are first leased (round_cutter.h),
    // into the vectors of the round before's (spare_).
    Round round_;
    std::vector<SampleJob> spare_;
    std::vector<JobSlot> jobs_;
    std::deque<size_t> pending_;  // the round out's jobs to lease, then the next's
    // Two rounds out: once every job of the round out is leased, a round the strategy
    // planned ahead opens, so workers trace it while the round out's last jobs are
    // traced and its end is worked out, instead of waiting on them. Its counts are the
    // strategy's (next_spp_, the very vector next_round hands over), its jobs follow the
    // round out's in jobs_ (from current_jobs_ on), and their results are held until the
    // round out has merged and ended, so every pixel's sums add up in round order and a
    // render's bytes do not depend on when a round opened. What is held is bounded:
    // results of at most half the image (next_pixels_, leased or held). Half, not a
    // quarter: a round is cut into at least two jobs a live worker core, so through the
    // round out's last jobs every core that finishes finds one of the round after; with a
    // quarter, at 64 worker cores and 1080p tiles of 128x128 (32 of them a quarter), half
    // the cores waited there (docs/FARM.md, "Two rounds out").
    size_t current_jobs_ = 0;
    const std::vector<uint32_t>* next_spp_ = nullptr;
    const uint32_t* next_data_ = nullptr;  // its buffer, which next_round hands over
    std::deque<size_t> next_pending_;
    size_t next_pixels_ = 0;
    bool next_tried_ = false;  // the round out's work ahead has been looked at
    bool announced_ = false;   // ... or announce_next_round said it could be
    bool opened_ahead_ = false;
    std::unordered_map<uint64_t, size_t> lease_to_job_;
    size_t merged_jobs_ = 0;
    // Jobs between begin_merge and end_merge, and the round ahead's held results.
    MergesInFlight merges_;
    JobFailures failures_;
    uint32_t rounds_done_ = 0;
    RoundSummary last_round_;

    double seconds_before_ = 0;
    std::optional<Clock::time_point> started_;  // start(), then its first lease
    bool leased_any_ = false;
    std::optional<double> final_seconds_;

    // Since when a lease found nothing while a plan made ahead was still being made.
    std::optional<Clock::time_point> plan_wait_since_;
    double plan_wait_seconds_ = 0;
    // A plan made ahead is running or done, and the round it may bring is not open yet.
    bool plan_coming() const { return !next_spp_ && !next_tried_ && work_ahead_.valid(); }
    // Ends that wait: counted when a round planned ahead came of the plan.
    void end_plan_wait(bool a_round_came);
    // A round end's plan runs on work_ahead_ (begin_next_round): no round is out.
    bool planning_round_end_ = false;

    // The strategy's work ahead, running on its own thread while the round's results
    // merge (it reads only what the strategy copied). Last, so that it is waited for
    // before the strategy it works on is destroyed.
    std::future<void> work_ahead_;
};

}  // namespace aliquot
