// Coordinator: every render's session, the leases handed to workers; the workers it has
// heard from and their links are its WorkerRegistry's (worker_registry.h); what it writes
// to disk and reads back (the SQLite record, checkpoints, images) is its RenderArchive's
// (render_archive.h), the farm's only includer of the store. Transport-free: the gRPC
// services and the embedded render call the same methods.
//
// Locks (docs/FARM.md, "Locks", has the order). The RenderList's lock (render_list.h)
// guards the render list only (renders by id and in order, the queue, priorities, the
// change counter) and is held for look-ups and bookkeeping. Each render has a lock of its
// own (RenderSlot::mutex) for everything its session does: issuing a job, merging a
// result, and ending a round (error estimate, checkpoint copy, planning and cutting the
// next one). A call finds its render in the list, works under the render's lock, and asks
// the list again to note what changed; the two are never held together. The LeaseTable,
// the WorkerRegistry, the memory budget, the scenes and the round-end counters have small
// locks of their own, taken under either or none; so leases and merges of different
// renders proceed in parallel, and a round end at 1920x1080 holds up that render's
// workers only.
#pragma once

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "checkpoint.h"
#include "lease_table.h"
#include "memory_budget.h"
#include "render_archive.h"
#include "render_events.h"
#include "render_info.h"
#include "render_list.h"
#include "render_session.h"
#include "round_end_stats.h"
#include "submitted_scenes.h"
#include "tick_schedule.h"
#include "ticker.h"
#include "worker_registry.h"

namespace aliquot {

struct CoordinatorOptions {
    std::filesystem::path data_dir;  // empty: in memory only (the embedded render)
    std::chrono::milliseconds lease_time{30000};
    std::chrono::milliseconds worker_lost_after{10000};
    uint32_t max_side = 8192;
    // Bytes the sessions in memory may use together (render_memory_estimate each); a
    // submission past it throws MemoryBudgetError. 0: no limit.
    uint64_t memory_limit = default_memory_limit();
    // Jobs workers cannot trace: how many failures fail a render, when a worker is kept
    // off one (docs/FARM.md). Failures count per worker host (the address its connection
    // came from), not per name: a name is the client's to choose, so one holder of the
    // worker token registering under three names is still one host.
    // Over the network, one host alone never fails a render unless the operator says so
    // (FailurePolicy::fail_on_fewer_hosts, --fail-on-fewer-hosts); workers in this
    // process (the embedded render) are trusted: for them the rule always holds.
    FailurePolicy failure_policy{.fail_on_fewer_hosts = false};
    // Worker sessions are forgotten after this long unheard while they hold no lease (a
    // worker that comes back is told to register again), and so are workers lost this
    // long, in memory and in the store; at most max_worker_sessions sessions and
    // max_workers workers (names) are remembered at once: registering past either drops
    // the longest-silent one holding no lease, or is refused with TooManyWorkers.
    // Every registration is remembered otherwise, and anyone with the worker token could
    // register without end.
    std::chrono::milliseconds forget_workers_after{std::chrono::hours(1)};
    size_t max_worker_sessions = 4096;
    size_t max_workers = 4096;
    // Workers (names) and sessions from one address at once (WorkerLimits): past either,
    // a Register from it drops its own lost ones or is refused with TooManyWorkers.
    size_t max_workers_per_host = 1024;
    // Finished renders are deleted (files, rows, memory) this long after they finished;
    // zero keeps them for ever. Checked once a minute (tick), or every quarter of it when
    // that is shorter.
    std::chrono::milliseconds keep_finished{0};
};

// Thrown by set_priority for a render that has finished.
class RenderFinished : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

class Coordinator : public WorkerLink {
public:
    explicit Coordinator(CoordinatorOptions options);
    ~Coordinator() override;

    // Client side. submit throws std::invalid_argument (bad spec), SceneError or
    // MemoryBudgetError.
    std::string submit(RenderSpec spec);
    std::optional<RenderInfo> info(const std::string& id);
    // RenderSession::plan_wait_seconds of a render in memory (bench/farm_scale).
    std::optional<double> plan_wait_seconds(const std::string& id);
    std::vector<RenderInfo> list(size_t limit);
    std::optional<RenderInfo> cancel(const std::string& id);
    // Changes a queued or running render's priority: its next leases follow it. Nullopt
    // for an unknown render; throws RenderFinished for a finished one.
    std::optional<RenderInfo> set_priority(const std::string& id, int32_t priority);
    // Deletes a finished render: its files, its rows (rounds, study links; its scene and
    // reference when nothing else uses them) and its memory. Nothing deletes a queued or
    // running render: cancel it first.
    enum class Removal { Removed, Unknown, Unfinished };
    Removal remove(const std::string& id);
    // Deletes the renders that finished more than keep_finished before `now_ms`; how
    // many. tick() calls it about once a minute.
    size_t remove_expired(int64_t now_ms);
    std::optional<Image> image(const std::string& id, bool aovs);
    // The stored EXR (every layer) of a finished render that has left memory; nullopt
    // while it is in memory, or when there is none: what FetchImage sends as it reads.
    std::optional<std::filesystem::path> image_file(const std::string& id);
    // Runs `read` on the merged sums of a render in memory, under its lock (merges
    // wait): a thumbnail is made from them without a full-size image. False, without
    // calling it, when the render is not in memory.
    bool read_sums(const std::string& id,
                   const std::function<void(const Accumulator&)>& read);
    std::vector<WorkerStatus> workers();
    // The render's events numbered after `after_seq` (-1: from its first), at most
    // `limit` (render_events.h); nullopt for an unknown render.
    std::optional<EventPage> events(const std::string& id, int64_t after_seq,
                                    size_t limit);
    // A counter that grows whenever any render changes; waits up to `timeout` for it to
    // pass `seen` and returns it.
    uint64_t wait_for_change(uint64_t seen, std::chrono::milliseconds timeout);

    // Worker side (WorkerLink, in-process). register_worker issues a new session each
    // call; every other call takes one and throws WorkerUnknown for a session it did not
    // issue. A lease is its session's: complete/renew/abandon/fail from another session
    // are refused and change nothing (docs/SECURITY.md, "Lease ownership").
    // In this process: the worker is trusted, and its name is its identity.
    Registration register_worker(const std::string& name, uint32_t threads) override;
    // Over the network: `peer` is where the call came from as the transport saw it
    // (gRPC's ServerContext::peer(), "ipv4:10.0.0.5:41234"); its host, without the port,
    // is the identity failures count against (FailurePolicy).
    // What a registered worker says of itself (its host name and release), shown in the
    // workers list and deciding nothing; an unknown name is ignored.
    void describe_worker(const std::string& name, std::string host, std::string version);
    Registration register_worker(const std::string& name, uint32_t threads,
                                 const std::string& peer);
    std::optional<LeaseGrant> lease(const std::string& session,
                                    std::chrono::milliseconds wait) override;
    // A result's sums are added off the render's lock (RenderSession::begin_merge), so
    // results of one render's disjoint jobs merge at once.
    CompleteOutcome complete(const std::string& session, uint64_t lease_id,
                             const SampleJobResult& result) override;
    // The same, a result held for the round ahead taken by move, not copied.
    CompleteOutcome complete(const std::string& session, uint64_t lease_id,
                             SampleJobResult&& result);
    std::optional<std::string> fetch_scene(const std::string& session,
                                           const std::string& hash) override;
    bool renew(const std::string& session, uint64_t lease_id) override;
    bool abandon(const std::string& session, uint64_t lease_id) override;
    bool fail(const std::string& session, uint64_t lease_id,
              const std::string& reason) override;
    // Whether `name` registered with this coordinator (a worker that did so with one
    // before a restart did not). Calls are refused by session, not by this: a name
    // proves nothing (WorkerRegistry::link_of).
    bool knows_worker(const std::string& name);
    // Leases out now, across renders (what `leases_` holds): for tests.
    size_t leases_out();
    // Worker sessions remembered now: for tests.
    size_t worker_sessions();
    // Submitted scenes held in memory now (those of the renders in memory): for tests.
    size_t scenes_in_memory();
    // Wall seconds, over all renders, of the Complete calls that ended a round, under the
    // render's lock: what the coordinator costs per round (round_end_stats.h); their CPU
    // time on their threads (what they cost whatever the load); the part the workers
    // waited through; the rounds ended.
    double round_end_seconds() const { return round_ends_.totals().seconds; }
    double round_end_cpu_seconds() const { return round_ends_.totals().cpu_seconds; }
    double round_end_wait_seconds() const { return round_ends_.totals().wait_seconds; }
    uint64_t rounds_ended() const { return round_ends_.totals().rounds; }

    // Why writes to the run record are failing (a full disk), empty when they are not.
    std::string storage_warning();

    // Counters and counts for the metrics (coordinator/api/metrics.h). Samples merged
    // and failed attempts to write the run record, since this process started (they only
    // grow); renders by state, as the run record has them (in memory: the sessions).
    uint64_t samples_merged() const;
    uint64_t store_write_failures() const;
    std::map<RenderState, uint64_t> render_counts();

    // The renders held in memory and their estimated bytes (render_memory_estimate). With
    // a data directory a finished render leaves memory once its end is recorded (image,
    // state); its info, image, rounds and buckets are then read from the store and disk.
    size_t sessions_in_memory();
    uint64_t memory_in_use() const { return memory_.in_use(); }
    // What a decoded reference for a width x height render may take (decode_exr's
    // max_bytes; MemoryBudget::reference_allowance). Asked before a reference is
    // decoded: its header alone can claim gigabytes.
    uint64_t reference_allowance(uint32_t width, uint32_t height) const {
        return memory_.reference_allowance(width, height);
    }

    // Expires leases, marks lost workers, checkpoints the WAL. A background thread calls
    // it.
    void tick();
    // Wakes every waiting call and refuses new leases: the first step of shutting down.
    void stop();

    // For tests: holds render `id`'s lock, as a long merge or round end of it would,
    // until the lock returned is let go (an empty one for an unknown render).
    std::unique_lock<std::mutex> hold_render_for_test(const std::string& id);
    // For tests: RenderSession::while_adding of render `id` (called off its lock, in
    // each merge between its check and its add).
    void set_while_adding_for_test(const std::string& id,
                                   std::function<void(size_t job)> hook);
    // For tests: runs `f` on render `id`'s session under its lock (to set its other test
    // hooks). These three are in coordinator_test_hooks.cpp.
    void with_session_for_test(const std::string& id,
                               const std::function<void(RenderSession&)>& f);

private:
    // complete's: `movable` is `result` when the caller gives it up, else null.
    CompleteOutcome complete_result(const std::string& session, uint64_t lease_id,
                                    const SampleJobResult& result,
                                    SampleJobResult* movable);
    void resume_unfinished();
    // Wires a new session's callbacks, starts it and makes it visible (RenderList::add).
    // `queued`: none of its jobs was leased yet (a submission, or a resumed render the
    // store has queued); it waits in the list's queue until one is.
    void attach(std::unique_ptr<RenderSession> session, bool queued);
    // Its first job was leased: out of the queue, so running in the record and the log.
    void note_started(const std::string& id);
    // A new link of worker `name` (WorkerRegistry::register_link) as a Registration.
    Registration register_link(const std::string& name, uint32_t threads,
                               std::string identity, bool trusted);
    // The worker holding `session` (touched, or WorkerUnknown) and the render whose
    // lease `lease_id` it holds (null when it holds none).
    std::pair<WorkerRegistry::Link, SlotPtr> holder_and_render(const std::string& session,
                                                               uint64_t lease_id);
    // The policy a failure of `caller` is counted with: the options', with the rule for
    // farms of fewer hosts always on for a trusted (in-process) worker.
    FailurePolicy failure_policy_of(const WorkerRegistry::Link& caller) const;
    // Drops a finished render whose end is recorded, and what is kept per render.
    void evict(const std::string& id);

    CoordinatorOptions options_;
    RenderArchive archive_;  // the store, the backlog of writes, the render directories
    // The renders in memory, under the coordinator-wide lock, and what waits on them.
    RenderList renders_;
    // Each of these has its own lock, a leaf (or, for the registry, taken before the
    // lease table's only).
    LeaseTable leases_;       // every lease out, its holder and its label
    MemoryBudget memory_;     // the renders in memory and submissions being set up
    SubmittedScenes scenes_;  // the scenes of the renders in memory
    TickSchedule tick_schedule_;
    RoundEndStats round_ends_;
    std::atomic<uint64_t> samples_merged_{0};  // atomic: read without the lock
    RenderEvents events_;
    WorkerRegistry registry_;         // the workers and their links
    std::unique_ptr<Ticker> ticker_;  // started last, once the renders are resumed

    // ---- Read-only views for the HTTP API and dashboard (http_server.h) ----
public:
    // The completed rounds of `id` in order, or nullopt for an unknown render. A live
    // render's come from memory; a render resumed or finished before this process started
    // reads the store's record (once, then cached for a live one).
    std::optional<std::vector<RoundSummary>> rounds(const std::string& id);
    // The strategy's current buckets for a live render, or those recorded with the last
    // round of an older one; empty for per-pixel methods; nullopt for an unknown render.
    std::optional<std::vector<Bucket>> buckets(const std::string& id);
};

}  // namespace aliquot
