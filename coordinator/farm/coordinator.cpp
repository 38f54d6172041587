#include "coordinator.h"

#include <malloc.h>

#include <stdexcept>

#include "checkpoint.h"
#include "farm_log.h"
#include "lease_scan.h"
#include "scene_loader.h"
#include "unix_millis.h"

namespace aliquot {

namespace {

// So a render counts the same at submission and eviction.
uint64_t memory_of(const RenderSpec& spec) {
    return method_memory_estimate(spec.width, spec.height, spec.reference.has_value(),
                                  spec.aux, spec.strategy.method);
}

}  // namespace

Coordinator::Coordinator(CoordinatorOptions options)
    : options_(std::move(options)),
      archive_(options_.data_dir),
      memory_(options_.memory_limit),
      tick_schedule_(options_.keep_finished),
      registry_({options_.worker_lost_after, options_.forget_workers_after,
                 options_.max_worker_sessions, options_.max_workers,
                 options_.max_workers_per_host, working_window(options_.lease_time)},
                archive_, events_, [this] { return leases_.leases_by_link(); }) {
    if (archive_.keeps_records()) {
        events_.record_to(archive_.store(), &archive_.backlog());
        resume_unfinished();
    }
    ticker_ =
        std::make_unique<Ticker>(std::chrono::milliseconds(200), [this] { tick(); });
}

Coordinator::~Coordinator() {
    stop();
    tick();  // the workers' last samples reach the store
    // What waits is written before the sessions its writes read go away.
    archive_.finish_writes();
}

void Coordinator::stop() {
    renders_.stop();
    if (ticker_) ticker_->stop();
}

void Coordinator::attach(std::unique_ptr<RenderSession> session, bool queued) {
    renders_.add(std::move(session), [&](RenderSlot& slot) {
        RenderSlot* raw = &slot;  // the slot owns the session: it outlives the callbacks
        RenderSession* s = slot.session.get();
        s->on_round = [this, raw](RenderSession& r, const RoundSummary& round) {
            events_.on_render(EventKind::RoundEnded, r.id(), round_fields(round));
            archive_.record_round(*raw, round);
        };
        // A held result counts once it merges, as complete counts any other.
        s->on_held_merged = [this](const MergesInFlight::Credit& c) noexcept {
            samples_merged_ += c.samples;
            registry_.note_merged(c.worker, c.samples, c.wall_seconds);  // no allocation
        };
        s->on_finished = [this, raw](RenderSession& r) {
            events_.on_render(end_event(r.state()), r.id(), end_fields(r));
            archive_.record_end(*raw, [this](const std::string& id) { evict(id); });
        };
        s->set_worker_cores(registry_.alive_cores());  // the first round is cut for them
        s->start();
        const bool waits = queued && s->state() == RenderState::Running;
        if (s->state() == RenderState::Running) {
            if (!waits) archive_.record_running(s->id());
            archive_.prepare_checkpoint_copy(slot);
        }
        return waits;
    });
}

void Coordinator::note_started(const std::string& id) {
    archive_.record_running(id);
    events_.on_render(EventKind::Started, id);
}

std::string Coordinator::submit(RenderSpec spec) {
    validate(spec, options_.max_side);
    // Parse now so a broken scene is the submitter's error, not every worker's.
    parse_submitted_scene(spec.scene_json,
                          spec.scene_name.empty() ? "scene" : spec.scene_name);
    const std::string hash = scene_hash(spec.scene_json);
    const uint64_t needed = memory_of(spec);
    // Before anything is claimed or written: a refused render leaves no trace. Counted
    // from now, so that submissions meanwhile see it; given back when it leaves memory.
    memory_.claim(needed, render_memory_note(spec.width, spec.height,
                                             spec.strategy.method == "denoised"));
    std::string id;
    bool recorded = false;  // its row is in the store
    bool scene_kept = false;
    // Building the session (its buffers) and writing its record and reference happen
    // off the lock: a 1920x1080 reference is 24 MB to write.
    try {
        id = archive_.claim_render_id();
        const int64_t created = unix_millis_now();
        auto session = std::make_unique<RenderSession>(id, spec, created);
        archive_.record_submission(id, spec, hash, created, session->samples_planned());
        recorded = true;
        scenes_.keep(hash, spec.scene_json);
        scene_kept = true;
        events_.on_render(EventKind::Submitted, id, submitted_fields(spec));
        attach(std::move(session), true);
    } catch (...) {
        memory_.release(needed);
        if (scene_kept) scenes_.drop(hash);
        // A render whose row was written keeps its directory, as the row points to it.
        if (!id.empty() && !recorded) archive_.unclaim(id);
        throw;
    }
    return id;
}

void Coordinator::resume_unfinished() {
    archive_.resume_unfinished([this](RenderArchive::Resumed r) {
        const std::string id = r.session->id();
        const RenderSpec& spec = r.session->spec();
        memory_.hold(memory_of(spec));
        scenes_.keep(r.scene_hash, spec.scene_json);
        events_.resume(id);
        events_.on_render(EventKind::Resumed, id);
        attach(std::move(r.session), r.queued);
    });
}

std::optional<double> Coordinator::plan_wait_seconds(const std::string& id) {
    const SlotPtr slot = renders_.find(id);
    if (!slot) return std::nullopt;
    std::lock_guard lock(slot->mutex);
    return slot->session->plan_wait_seconds();
}

std::optional<RenderInfo> Coordinator::info(const std::string& id) {
    const RenderList::Place place = renders_.place_of(id);
    if (const SlotPtr& slot = place.slot) {
        std::lock_guard lock(slot->mutex);
        RenderInfo out = info_of(*slot->session, place.priority);
        if (place.queued_at > 0 && out.state == RenderState::Running) {
            out.state =
                RenderState::Queued;  // the session is ready; no worker has it yet
            out.queue_position = place.queued_at;
        }
        return out;
    }
    // Not in memory: finished and evicted (its end is in the store), or unknown.
    return archive_.stored_info(id);
}

std::vector<RenderInfo> Coordinator::list(size_t limit) {
    const std::vector<std::string> ids = archive_.keeps_records()
                                             ? archive_.recent_ids(limit)
                                             : renders_.newest_ids(limit);
    std::vector<RenderInfo> out;
    for (const std::string& id : ids)
        if (auto i = info(id)) out.push_back(std::move(*i));
    return out;
}

std::optional<RenderInfo> Coordinator::cancel(const std::string& id) {
    const SlotPtr slot = renders_.find(id);
    if (slot) {
        {
            std::lock_guard lock(slot->mutex);
            slot->session->cancel();
        }
        renders_.cancelled(id, leases_);
    } else if (!archive_.knows(id)) {
        return std::nullopt;
    }
    return info(id);
}

std::optional<RenderInfo> Coordinator::set_priority(const std::string& id,
                                                    int32_t priority) {
    const SlotPtr slot = renders_.find(id);
    bool finished = true;
    if (slot) {
        std::lock_guard render(slot->mutex);
        finished = slot->session->finished();
    } else if (!archive_.knows(id)) {
        return std::nullopt;
    }
    if (finished)
        throw RenderFinished("render " + id + " has finished: nothing to schedule");
    renders_.set_priority(slot, priority);  // waiting workers look again, in its order
    // The store is written after the order changes: a full disk delays the record, not
    // the scheduling. A restart before it lands resumes the old priority.
    archive_.record_priority(id, priority);
    return info(id);
}

Coordinator::Removal Coordinator::remove(const std::string& id) {
    const SlotPtr slot = renders_.find(id);
    if (slot) {
        {
            std::lock_guard render(slot->mutex);
            if (!slot->session->finished()) return Removal::Unfinished;
        }
        if (!archive_.keeps_records()) {
            evict(id);
            return Removal::Removed;
        }
        // Finished, and its end is being written (then it leaves memory): wait for that,
        // but not for a disk that refuses it. The writes wait in order, and on a full
        // disk they are retried for as long as it is full: waiting for the whole backlog
        // held the caller (an HTTP thread) for 30 s, and then failed anyway.
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        std::string failing;
        if (renders_.wait_until_gone(
                id, deadline, [&] { return !(failing = archive_.warning()).empty(); }))
            throw std::runtime_error("render " + id + " is still being written to disk" +
                                     (failing.empty() ? "" : " (" + failing + ")") +
                                     "; try again later");
    }
    switch (archive_.delete_render(id)) {
        case RenderArchive::Deletion::Unknown:
            return Removal::Unknown;
        case RenderArchive::Deletion::Unfinished:
            return Removal::Unfinished;
        case RenderArchive::Deletion::Deleted:
            break;
    }
    renders_.note_change();
    return Removal::Removed;
}

size_t Coordinator::remove_expired(int64_t now_ms) {
    if (!archive_.keeps_records() || options_.keep_finished.count() <= 0) return 0;
    size_t removed = 0;
    // In batches, so that a first run over years of renders does not list them all.
    for (;;) {
        const std::vector<std::string> ids =
            archive_.finished_before(now_ms - options_.keep_finished.count(), 100);
        size_t batch = 0;
        for (const std::string& id : ids) {
            try {
                if (remove(id) == Removal::Removed) ++batch;
            } catch (const std::exception& e) {
                log_farm_error("retention: cannot delete " + id + ": " + e.what());
            }
        }
        removed += batch;
        if (batch == 0 || ids.size() < 100) return removed;
    }
}

std::optional<Image> Coordinator::image(const std::string& id, bool aovs) {
    const SlotPtr slot = renders_.find(id);
    if (slot) {
        std::lock_guard lock(slot->mutex);
        return slot->session->image(aovs);
    }
    return archive_.stored_image(id, aovs);
}

bool Coordinator::read_sums(const std::string& id,
                            const std::function<void(const Accumulator&)>& read) {
    const SlotPtr slot = renders_.find(id);
    if (!slot) return false;
    std::lock_guard lock(slot->mutex);
    slot->session->wait_for_adds();  // its pixels as the merges counted made them
    read(slot->session->merged());
    return true;
}

std::optional<std::filesystem::path> Coordinator::image_file(const std::string& id) {
    if (renders_.contains(id)) return std::nullopt;
    return archive_.image_file(id);
}

uint64_t Coordinator::wait_for_change(uint64_t seen, std::chrono::milliseconds timeout) {
    return renders_.wait_for_change(seen, timeout);
}

FailurePolicy Coordinator::failure_policy_of(const WorkerRegistry::Link& caller) const {
    FailurePolicy policy = options_.failure_policy;
    if (caller.trusted) policy.fail_on_fewer_hosts = true;  // the embedded render's
    return policy;
}

Registration Coordinator::register_worker(const std::string& name, uint32_t threads) {
    return register_link(name, threads, "process:" + name, true);
}

Registration Coordinator::register_worker(const std::string& name, uint32_t threads,
                                          const std::string& peer) {
    return register_link(name, threads, host_of_peer(peer), false);
}

void Coordinator::describe_worker(const std::string& name, std::string host,
                                  std::string version) {
    if (registry_.describe(name, std::move(host), std::move(version)))
        renders_.note_change();
}

Registration Coordinator::register_link(const std::string& name, uint32_t threads,
                                        std::string identity, bool trusted) {
    std::string link =
        registry_.register_link(name, threads, std::move(identity), trusted);
    renders_.note_change();
    return {std::move(link), uint32_t(options_.lease_time.count())};
}

std::optional<LeaseGrant> Coordinator::lease(const std::string& session,
                                             std::chrono::milliseconds wait) {
    // Jobs are the session's host's to take: RenderSession counts failures, keeps hosts
    // off jobs and checks lease ownership by this, and the Coordinator checks ownership
    // by session before it asks.
    const std::string worker = registry_.link_of(session).identity;
    const WorkerRegistry::Poll poll(registry_, session);
    const auto deadline = std::chrono::steady_clock::now() + wait;
    while (const std::optional<RenderList::Snapshot> renders = renders_.by_priority()) {
        const std::vector<SlotPtr>& slots = renders->slots;
        const std::shared_ptr<const std::set<std::string>> alive =
            registry_.alive_identities();
        const size_t cores = registry_.alive_cores();
        // Reserved now, so that no other lease takes the id while it is being issued.
        const uint64_t lease_id = leases_.reserve(session);
        LeaseScan scan =
            scan_for_a_job(slots, {lease_id, worker, options_.lease_time, alive.get(),
                                   options_.failure_policy, cores});
        std::optional<LeaseGrant>& grant = scan.grant;
        if (grant)
            leases_.grant(lease_id, grant->render_id, std::move(scan.label));
        else
            leases_.end(lease_id);
        // As complete does for a render its merge failed.
        if (!scan.failed.empty()) renders_.note_ended(leases_, {}, scan.failed);
        if (grant) {
            if (renders_.leased(grant->render_id)) note_started(grant->render_id);
            return grant;
        }
        // Whatever could give this worker a job (a round planned, a lease given back or
        // expired, a worker lost) moves the list's change counter: nothing is missed
        // between the snapshot above and this wait. A round planned ahead whose plan ends
        // on the session's thread is announced by tick(), within its 200 ms.
        if (!renders_.wait_for_work(renders->seen, deadline)) break;
    }
    return std::nullopt;
}

CompleteOutcome Coordinator::complete(const std::string& session, uint64_t lease_id,
                                      const SampleJobResult& result) {
    return complete_result(session, lease_id, result, nullptr);
}

CompleteOutcome Coordinator::complete(const std::string& session, uint64_t lease_id,
                                      SampleJobResult&& result) {
    return complete_result(session, lease_id, result, &result);
}

CompleteOutcome Coordinator::complete_result(const std::string& session,
                                             uint64_t lease_id,
                                             const SampleJobResult& result,
                                             SampleJobResult* movable) {
    const WorkerRegistry::Link caller = registry_.link_of(session);
    // Whatever the outcome, a lease held has ended here. Someone else's lease is refused
    // before anything is looked at, and it stays with its holder, whose own result still
    // merges.
    const LeaseTable::Held held = leases_.take(lease_id, session);
    if (held.holding == LeaseTable::Holding::Unknown)
        return {CompleteStatus::Ignored, "unknown, expired or already merged lease"};
    if (held.holding == LeaseTable::Holding::NotYours)
        return {CompleteStatus::Ignored, "not your lease"};
    const SlotPtr slot = renders_.find(held.render);
    if (!slot) return {CompleteStatus::Ignored, "the render is no longer here"};
    const std::shared_ptr<const std::set<std::string>> alive =
        registry_.alive_identities();
    const size_t cores = registry_.alive_cores();
    const FailurePolicy policy = failure_policy_of(caller);
    const double wall_seconds = result.wall_seconds;  // `movable` may be taken
    // The lease checked and the job marked merging under the render's lock; the sums
    // added off it (the slot, held here, keeps the session and its buffers); the merge
    // counted, and when it is the round's last the round ended, under it again.
    RenderSession& s = *slot->session;
    RenderSession::Merge merge;
    RoundEnd round_end;
    bool render_failed = false;
    try {
        std::unique_lock render(slot->mutex);
        s.set_worker_cores(cores);  // the next round is cut for them
        // A rejected result counts as a failure.
        merge = s.begin_merge(lease_id, caller.identity, result, movable, *alive, policy,
                              caller.worker);
        render_failed = s.state() == RenderState::Failed;
        if (!merge.outcome) {
            render.unlock();
            s.add_merge(merge, result);
            render.lock();
            const RoundEndMeter meter(s);
            merge.outcome = s.end_merge(merge, *alive, policy);
            round_end = meter.finish(s);
            render_failed = s.state() == RenderState::Failed;
        }
    } catch (...) {
        // A job given back (a merge that could not keep what it needs, a refusal whose
        // count failed) can be leased now: waiting leases hear of it, as of any requeue.
        renders_.note_change();
        throw;
    }
    round_ends_.add(round_end);
    if (merge.outcome->status == CompleteStatus::Merged && !merge.held) {
        samples_merged_ += merge.totals.samples;
        registry_.note_merged(caller.worker, merge.totals.samples, wall_seconds);
    }
    if (render_failed)
        renders_.note_ended(leases_, {}, {s.id()});
    else
        renders_.note_change();
    return *merge.outcome;
}

std::optional<std::string> Coordinator::fetch_scene(const std::string& session,
                                                    const std::string& hash) {
    registry_.link_of(session);
    if (std::optional<std::string> scene = scenes_.find(hash)) return scene;
    return archive_.stored_scene(hash);
}

std::pair<WorkerRegistry::Link, SlotPtr> Coordinator::holder_and_render(
    const std::string& session, uint64_t lease_id) {
    WorkerRegistry::Link caller = registry_.link_of(session);
    // Only the holder's word counts: anyone else's leaves the lease with its holder.
    const LeaseTable::Held held = leases_.held(lease_id, session);
    if (held.holding != LeaseTable::Holding::Held) return {std::move(caller), nullptr};
    return {std::move(caller), renders_.find(held.render)};
}

bool Coordinator::renew(const std::string& session, uint64_t lease_id) {
    const auto [caller, slot] = holder_and_render(session, lease_id);
    if (!slot) return false;
    std::lock_guard render(slot->mutex);
    return slot->session->renew(lease_id, caller.identity,
                                RenderSession::Clock::now() + options_.lease_time);
}

bool Coordinator::abandon(const std::string& session, uint64_t lease_id) {
    const auto [caller, slot] = holder_and_render(session, lease_id);
    if (!slot) return false;
    {
        std::lock_guard render(slot->mutex);
        if (!slot->session->abandon(lease_id, caller.identity)) return false;
    }
    leases_.end(lease_id);
    renders_.note_change();
    return true;
}

bool Coordinator::fail(const std::string& session, uint64_t lease_id,
                       const std::string& reason) {
    const auto [caller, slot] = holder_and_render(session, lease_id);
    if (!slot) return false;
    const std::shared_ptr<const std::set<std::string>> alive =
        registry_.alive_identities();
    bool render_failed = false;
    try {
        std::lock_guard render(slot->mutex);
        RenderSession& s = *slot->session;
        if (!s.fail_job(lease_id, caller.identity, reason, *alive,
                        failure_policy_of(caller)))
            return false;
        if (s.failures_of(caller.identity) == options_.failure_policy.blocklist_after)
            events_.on_render(
                EventKind::WorkerBlocklisted, s.id(),
                {log_text("worker", caller.worker), log_text("host", caller.identity),
                 log_text("reason", reason)});
        render_failed = s.state() == RenderState::Failed;
        if (render_failed) log_farm_error(s.id() + " failed: " + s.error());
    } catch (...) {
        // The lease has ended and its job is queued again (fail_job), as complete's.
        leases_.end(lease_id);
        renders_.note_change();
        throw;
    }
    leases_.end(lease_id);
    registry_.note_failure(caller.worker);
    // The render's other leases ended with it.
    if (render_failed)
        renders_.note_ended(leases_, {}, {slot->session->id()});
    else
        renders_.note_change();
    return true;
}

bool Coordinator::knows_worker(const std::string& name) { return registry_.knows(name); }

size_t Coordinator::leases_out() { return leases_.size(); }

uint64_t Coordinator::samples_merged() const { return samples_merged_; }

uint64_t Coordinator::store_write_failures() const { return archive_.write_failures(); }

std::map<RenderState, uint64_t> Coordinator::render_counts() {
    // The store is read off the coordinator's lock, as list() reads it.
    if (archive_.keeps_records()) return archive_.counts_by_state();
    // A session is Running from its submission; it counts as Queued while no job of it
    // has been leased, as info() and list() show it.
    std::map<RenderState, uint64_t> counts;
    for (const auto& [slot, queued] : renders_.in_order_with_queued()) {
        std::lock_guard render(slot->mutex);
        const RenderState state = slot->session->state();
        ++counts[queued && state == RenderState::Running ? RenderState::Queued : state];
    }
    return counts;
}

size_t Coordinator::worker_sessions() { return registry_.links(); }

std::vector<WorkerStatus> Coordinator::workers() {
    // Each lease keeps its label, so no render's lock is taken.
    return registry_.statuses(leases_.labels_by_link());
}

std::string Coordinator::storage_warning() { return archive_.warning(); }

void Coordinator::tick() {
    // Leases past their deadline go back to their renders' queues, under each render's
    // lock; then, under the coordinator's, they and the leases of renders finished
    // since are gone for good.
    const LeaseSweep swept =
        sweep_leases(renders_.in_order(), RenderSession::Clock::now());
    const TickChores due = tick_schedule_.next();
    const bool lost = registry_.tick(unix_millis_now(), due.sweep_worker_rows);
    renders_.note_ended(leases_, swept.expired, swept.finished,
                        !swept.expired.empty() || swept.opened_ahead || lost);
    archive_.tick(due.wal_checkpoint);
    // Outside the lock: deleting a render's files can take a while.
    if (due.retention) {
        try {
            remove_expired(unix_millis_now());
        } catch (const std::exception& e) {
            log_farm_error(std::string("retention: ") +
                           e.what());  // tried again next time
        }
    }
}

// ---- Read-only views for the HTTP API and dashboard ----

std::optional<std::vector<RoundSummary>> Coordinator::rounds(const std::string& id) {
    const SlotPtr slot = renders_.find(id);
    if (slot) {
        std::lock_guard render(slot->mutex);
        archive_.complete_history(*slot);
        return slot->round_history;
    }
    return archive_.stored_rounds(id);
}

std::optional<EventPage> Coordinator::events(const std::string& id, int64_t after_seq,
                                             size_t limit) {
    return events_.read(id, after_seq, limit);
}

std::optional<std::vector<Bucket>> Coordinator::buckets(const std::string& id) {
    const SlotPtr slot = renders_.find(id);
    if (slot) {
        std::lock_guard render(slot->mutex);
        return slot->session->strategy().buckets();
    }
    return archive_.stored_buckets(id);
}

// ---- Finished renders leaving memory ----

size_t Coordinator::sessions_in_memory() { return renders_.size(); }

size_t Coordinator::scenes_in_memory() { return scenes_.size(); }

void Coordinator::evict(const std::string& id) {
    const bool dropped = renders_.drop_finished(id, [this](RenderSession& s) {
        memory_.release(memory_of(s.spec()));
        scenes_.drop(s.scene_hash());
        events_.forget(s.id());  // its events are the store's to serve now
        // Leases of a cancelled render that workers still hold: their results are now
        // answered as unknown, which is what they were (ignored) before.
        leases_.forget_render(s.id());
    });
    if (!dropped) return;
    // glibc keeps freed pages of its arenas for reuse; a finished render's buffers are
    // tens of megabytes, and given back they let the coordinator's size follow its live
    // renders rather than its busiest moment.
    malloc_trim(0);
}

}  // namespace aliquot
