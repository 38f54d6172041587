#include "coordinator.h"

#include <fcntl.h>
#include <malloc.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <stdexcept>

#include "bands.h"
#include "checkpoint.h"
#include "farm_log.h"
#include "scene_loader.h"
#include "unix_millis.h"

namespace aliquot {

namespace {

double thread_cpu_seconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

}  // namespace

Coordinator::Coordinator(CoordinatorOptions options)
    : options_(std::move(options)),
      archive_(options_.data_dir),
      registry_({options_.worker_lost_after, options_.forget_workers_after,
                 options_.max_worker_sessions, options_.max_workers},
                archive_, events_, [this] { return leases_.links_holding(); }) {
    if (archive_.keeps_records()) {
        events_.record_to(archive_.store(), &archive_.backlog());
        resume_unfinished();
    }
    ticker_ = std::thread([this] {
        while (true) {
            {
                std::unique_lock lock(mutex_);
                if (progress_.wait_for(lock, std::chrono::milliseconds(200),
                                       [this] { return stopping_; }))
                    return;
            }
            // Nothing the ticker meets may end the process: it logs and ticks again.
            try {
                tick();
            } catch (const std::exception& e) {
                log_farm_error(std::string("tick: ") + e.what());
            }
        }
    });
}

Coordinator::~Coordinator() {
    stop();
    if (ticker_.joinable()) ticker_.join();
    tick();  // the workers' last samples reach the store
    // What waits is written before the sessions its writes read go away.
    archive_.finish_writes();
}

void Coordinator::stop() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    progress_.notify_all();
    work_ready_.notify_all();
}

void Coordinator::changed() {
    ++version_;
    progress_.notify_all();
    work_ready_.notify_all();
}

SlotPtr Coordinator::slot_of(const std::string& id) const {
    const auto it = sessions_.find(id);
    return it == sessions_.end() ? nullptr : it->second;
}

std::vector<SlotPtr> Coordinator::slots_in_order() const {
    std::vector<SlotPtr> out;
    out.reserve(order_.size());
    for (const std::string& id : order_) out.push_back(sessions_.at(id));
    return out;
}

std::vector<SlotPtr> Coordinator::slots_by_priority() const {
    std::vector<SlotPtr> out = slots_in_order();
    std::stable_sort(out.begin(), out.end(), [](const SlotPtr& a, const SlotPtr& b) {
        return a->priority > b->priority;
    });
    return out;
}

void Coordinator::attach(std::unique_ptr<RenderSession> session, bool queued) {
    auto slot = std::make_shared<RenderSlot>();
    RenderSlot* raw = slot.get();  // the slot owns the session: it outlives the callbacks
    RenderSession* s = session.get();
    s->on_round = [this, raw](RenderSession& r, const RoundSummary& round) {
        events_.on_render(EventKind::RoundEnded, r.id(), round_fields(round));
        archive_.record_round(*raw, round);
    };
    s->on_finished = [this, raw](RenderSession& r) {
        events_.on_render(end_event(r.state()), r.id(), end_fields(r));
        archive_.record_end(*raw, [this](const std::string& id) {
            std::lock_guard lock(mutex_);
            evict(id);
        });
    };
    slot->session = std::move(session);
    slot->priority = s->spec().priority;
    slot->number = submissions_++;
    order_.push_back(s->id());
    sessions_[s->id()] = std::move(slot);
    s->set_worker_cores(registry_.alive_cores());  // the first round is cut for them
    s->start();
    const bool waits = queued && s->state() == RenderState::Running;
    if (waits) queue_.add(s->id(), raw->priority, raw->number);  // running at its lease
    if (s->state() == RenderState::Running) {
        if (!waits) archive_.record_running(s->id());
        archive_.prepare_checkpoint_copy(*raw);
    }
    changed();
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
    const uint64_t needed =
        render_memory_estimate(spec.width, spec.height, spec.reference.has_value());
    std::string id;
    bool recorded = false;  // its row is in the store
    {
        std::lock_guard lock(mutex_);
        // Before anything is claimed or written: a refused render leaves no trace.
        const uint64_t in_use = memory_in_use_locked();
        if (options_.memory_limit > 0 &&
            (needed > options_.memory_limit || in_use > options_.memory_limit - needed))
            throw MemoryBudgetError(needed, in_use, sessions_.size(),
                                    options_.memory_limit);
        id = archive_.claim_render_id();
        // Counted until the session is attached, so that submissions meanwhile see it.
        reserved_memory_ += needed;
    }
    // Building the session (its buffers) and writing its record and reference happen
    // off the lock: a 1920x1080 reference is 24 MB to write.
    try {
        const int64_t created = unix_millis_now();
        auto session = std::make_unique<RenderSession>(id, spec, created);
        archive_.record_submission(id, spec, hash, created, session->samples_planned());
        recorded = true;
        std::lock_guard lock(mutex_);
        reserved_memory_ -= needed;
        scenes_[hash] = spec.scene_json;
        events_.on_render(EventKind::Submitted, id, submitted_fields(spec));
        attach(std::move(session), true);
    } catch (...) {
        {
            std::lock_guard lock(mutex_);
            reserved_memory_ -= needed;
            drop_scene_if_unused(hash);
        }
        // A render whose row was written keeps its directory, as the row points to it.
        if (!recorded) archive_.unclaim(id);
        throw;
    }
    return id;
}

void Coordinator::resume_unfinished() {
    archive_.resume_unfinished([this](RenderArchive::Resumed r) {
        const std::string id = r.session->id();
        std::lock_guard lock(mutex_);  // the backlog's thread may evict meanwhile
        scenes_[r.scene_hash] = r.session->spec().scene_json;
        events_.resume(id);
        events_.on_render(EventKind::Resumed, id);
        attach(std::move(r.session), r.queued);
    });
}

std::optional<double> Coordinator::plan_wait_seconds(const std::string& id) {
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
    if (!slot) return std::nullopt;
    std::lock_guard lock(slot->mutex);
    return slot->session->plan_wait_seconds();
}

std::optional<RenderInfo> Coordinator::info(const std::string& id) {
    SlotPtr slot;
    int32_t priority = 0;
    uint32_t queued_at = 0;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
        if (slot) priority = slot->priority;
        queued_at = queue_.position(id);
    }
    if (slot) {
        std::lock_guard lock(slot->mutex);
        RenderInfo out = info_of(*slot->session, priority);
        if (queued_at > 0 && out.state == RenderState::Running) {
            out.state =
                RenderState::Queued;  // the session is ready; no worker has it yet
            out.queue_position = queued_at;
        }
        return out;
    }
    // Not in memory: finished and evicted (its end is in the store), or unknown.
    return archive_.stored_info(id);
}

std::vector<RenderInfo> Coordinator::list(size_t limit) {
    std::vector<std::string> ids;
    if (archive_.keeps_records()) {
        ids = archive_.recent_ids(limit);
    } else {
        std::lock_guard lock(mutex_);
        for (auto it = order_.rbegin(); it != order_.rend() && ids.size() < limit; ++it)
            ids.push_back(*it);
    }
    std::vector<RenderInfo> out;
    for (const std::string& id : ids)
        if (auto i = info(id)) out.push_back(std::move(*i));
    return out;
}

std::optional<RenderInfo> Coordinator::cancel(const std::string& id) {
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
    if (slot) {
        {
            std::lock_guard lock(slot->mutex);
            slot->session->cancel();
        }
        std::lock_guard lock(mutex_);
        forget_ended_leases({}, {id});
        queue_.leave(id);
        changed();
    } else if (!archive_.knows(id)) {
        return std::nullopt;
    }
    return info(id);
}

std::optional<RenderInfo> Coordinator::set_priority(const std::string& id,
                                                    int32_t priority) {
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
    bool finished = true;
    if (slot) {
        std::lock_guard render(slot->mutex);
        finished = slot->session->finished();
    } else if (!archive_.knows(id)) {
        return std::nullopt;
    }
    if (finished)
        throw RenderFinished("render " + id + " has finished: nothing to schedule");
    {
        std::lock_guard lock(mutex_);
        slot->priority = priority;
        queue_.set_priority(id, priority);
        changed();  // waiting workers look again, in the new order
    }
    // The store is written after the order changes: a full disk delays the record, not
    // the scheduling. A restart before it lands resumes the old priority.
    archive_.record_priority(id, priority);
    return info(id);
}

Coordinator::Removal Coordinator::remove(const std::string& id) {
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
    if (slot) {
        {
            std::lock_guard render(slot->mutex);
            if (!slot->session->finished()) return Removal::Unfinished;
        }
        if (!archive_.keeps_records()) {
            std::lock_guard lock(mutex_);
            evict(id);
            return Removal::Removed;
        }
        // Finished, and its end is being written (then it leaves memory): wait for that,
        // but not for a disk that refuses it. The writes wait in order, and on a full
        // disk they are retried for as long as it is full: waiting for the whole backlog
        // held the caller (an HTTP thread) for 30 s, and then failed anyway.
        std::unique_lock lock(mutex_);
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        std::string failing;
        while (slot_of(id) && !stopping_ && (failing = archive_.warning()).empty() &&
               std::chrono::steady_clock::now() < deadline)
            // evict() wakes this; the backlog failing does not, hence the period.
            progress_.wait_for(lock, std::chrono::milliseconds(100));
        if (slot_of(id))
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
    {
        std::lock_guard lock(mutex_);
        changed();
    }
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
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
    if (slot) {
        std::lock_guard lock(slot->mutex);
        return slot->session->image(aovs);
    }
    return archive_.stored_image(id, aovs);
}

std::optional<std::filesystem::path> Coordinator::image_file(const std::string& id) {
    {
        std::lock_guard lock(mutex_);
        if (slot_of(id)) return std::nullopt;
    }
    return archive_.image_file(id);
}

uint64_t Coordinator::wait_for_change(uint64_t seen, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    progress_.wait_for(lock, timeout, [&] { return version_ > seen || stopping_; });
    return version_;
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
    std::lock_guard lock(mutex_);
    if (registry_.describe(name, std::move(host), std::move(version))) changed();
}

Registration Coordinator::register_link(const std::string& name, uint32_t threads,
                                        std::string identity, bool trusted) {
    std::lock_guard lock(mutex_);
    std::string link =
        registry_.register_link(name, threads, std::move(identity), trusted);
    changed();
    return {std::move(link), uint32_t(options_.lease_time.count())};
}

std::optional<LeaseGrant> Coordinator::lease(const std::string& session,
                                             std::chrono::milliseconds wait) {
    std::unique_lock lock(mutex_);
    // Jobs are the session's host's to take: RenderSession counts failures, keeps hosts
    // off jobs and checks lease ownership by this, and the Coordinator checks ownership
    // by session before it asks.
    const std::string worker = registry_.link_of(session).identity;
    const auto deadline = std::chrono::steady_clock::now() + wait;
    while (!stopping_) {
        const uint64_t seen = version_;
        const std::vector<SlotPtr> slots = slots_by_priority();
        const std::shared_ptr<const std::set<std::string>> alive =
            registry_.alive_identities();
        const size_t cores = registry_.alive_cores();
        // Reserved now, so that no other lease takes the id while the lock is let go.
        const uint64_t lease_id = leases_.reserve(session);
        lock.unlock();
        // Renders by priority, in submission order within one; one whose lock is busy (a
        // merge, or a round's end) is passed over at first and waited for only when no
        // other render has a job, so one render's round end holds up no other render's
        // workers.
        std::optional<LeaseGrant> grant;
        std::string label;  // the job's "render/job", for the workers list
        std::vector<RenderSlot*> busy;
        std::set<std::string> failed;  // renders a plan made ahead failed (issue)
        auto try_issue = [&](RenderSlot& slot) {
            RenderSession& s = *slot.session;
            if (s.state() != RenderState::Running || !s.has_pending()) return;
            s.set_worker_cores(cores);  // a round opened ahead here is cut for them
            std::optional<SampleJob> job = s.issue(
                lease_id, worker, RenderSession::Clock::now() + options_.lease_time,
                *alive, options_.failure_policy);
            if (s.state() == RenderState::Failed) failed.insert(s.id());
            if (!job) return;
            label = s.lease_label(lease_id);
            grant = LeaseGrant{
                lease_id,        s.id(),
                s.scene_hash(),  {s.spec().width, s.spec().height, s.spec().seed},
                std::move(*job), uint32_t(options_.lease_time.count())};
        };
        for (const SlotPtr& slot : slots) {
            std::unique_lock render(slot->mutex, std::try_to_lock);
            if (!render.owns_lock()) {
                busy.push_back(slot.get());
                continue;
            }
            try_issue(*slot);
            if (grant) break;
        }
        for (size_t i = 0; !grant && i < busy.size(); ++i) {
            std::lock_guard render(busy[i]->mutex);
            try_issue(*busy[i]);
        }
        lock.lock();
        if (!failed.empty()) {  // as complete does for a render its merge failed
            forget_ended_leases({}, failed);
            changed();
        }
        if (grant) {
            leases_.grant(lease_id, grant->render_id, std::move(label));
            if (queue_.leave(grant->render_id)) note_started(grant->render_id);
            changed();
            return grant;
        }
        leases_.end(lease_id);
        // Whatever could give this worker a job (a round planned, a lease given back or
        // expired, a worker lost) changes version_ under this lock: nothing is missed
        // between the scan above and this wait. A round planned ahead whose plan ends on
        // the session's thread is announced by tick(), within its 200 ms.
        if (!work_ready_.wait_until(lock, deadline,
                                    [&] { return version_ != seen || stopping_; }))
            break;
    }
    return std::nullopt;
}

CompleteOutcome Coordinator::complete(const std::string& session, uint64_t lease_id,
                                      const SampleJobResult& result) {
    WorkerRegistry::Link caller;
    SlotPtr slot;
    std::shared_ptr<const std::set<std::string>> alive;
    FailurePolicy policy;
    size_t cores = 0;
    {
        std::lock_guard lock(mutex_);
        caller = registry_.link_of(session);
        const LeaseTable::Lease* lease = leases_.find(lease_id);
        if (!lease || lease->render.empty())
            return {CompleteStatus::Ignored, "unknown, expired or already merged lease"};
        // Someone else's lease: refused before anything is looked at, and it stays with
        // its holder, whose own result still merges.
        if (lease->link != session) return {CompleteStatus::Ignored, "not your lease"};
        slot = slot_of(lease->render);
        leases_.end(lease_id);  // whatever the outcome, this lease has ended
        if (!slot) return {CompleteStatus::Ignored, "the render is no longer here"};
        alive = registry_.alive_identities();
        policy = failure_policy_of(caller);  // a rejected result counts as a failure
        cores = registry_.alive_cores();
    }
    // The merge, and when this is the round's last job the round's end, under the
    // render's lock alone.
    CompleteOutcome outcome;
    double round_end = 0, round_end_cpu = 0;
    uint32_t ended = 0;  // rounds this call ended
    bool waited = false;
    bool render_failed = false;
    {
        std::lock_guard render(slot->mutex);
        RenderSession& s = *slot->session;
        const uint32_t rounds_before = s.rounds_done();
        const auto began = std::chrono::steady_clock::now();
        // The band pool's threads work for the round end too (bands.h): their CPU time
        // counts. Another render's round end running meanwhile would be counted here as
        // well; farm_scale runs one render.
        const double began_cpu = thread_cpu_seconds() + band_pool_cpu_seconds();
        s.set_worker_cores(cores);  // the next round is cut for them
        outcome = s.complete(lease_id, caller.identity, result, *alive, policy);
        // This result ended a round, or two: the round after it, opened ahead, may have
        // merged whole by then. The call's time counts as waited through when the round
        // it left out was not opened ahead.
        if (s.rounds_done() != rounds_before) {
            ended = s.rounds_done() - rounds_before;
            round_end =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - began)
                    .count();
            round_end_cpu = thread_cpu_seconds() + band_pool_cpu_seconds() - began_cpu;
            waited = !(s.state() == RenderState::Running && s.round_opened_ahead());
        }
        render_failed = s.state() == RenderState::Failed;
    }
    std::lock_guard lock(mutex_);
    round_end_seconds_ += round_end;
    round_end_cpu_seconds_ += round_end_cpu;
    if (waited) round_end_wait_seconds_ += round_end;
    rounds_ended_ += ended;
    if (render_failed) forget_ended_leases({}, {slot->session->id()});
    if (outcome.status == CompleteStatus::Merged) {
        samples_merged_ += result.total_samples();
        registry_.note_merged(caller.worker, result.total_samples(), result.wall_seconds);
    }
    changed();
    return outcome;
}

std::optional<std::string> Coordinator::fetch_scene(const std::string& session,
                                                    const std::string& hash) {
    {
        std::lock_guard lock(mutex_);
        registry_.link_of(session);
        if (auto it = scenes_.find(hash); it != scenes_.end()) return it->second;
    }
    return archive_.stored_scene(hash);
}

SlotPtr Coordinator::held_render(const std::string& session, uint64_t lease_id) {
    // Only the holder's word counts: anyone else's leaves the lease with its holder.
    const LeaseTable::Lease* lease = leases_.find(lease_id);
    if (!lease || lease->link != session) return nullptr;
    return slot_of(lease->render);
}

std::pair<std::string, SlotPtr> Coordinator::holder_and_render(const std::string& session,
                                                               uint64_t lease_id) {
    std::lock_guard lock(mutex_);
    std::string worker = registry_.link_of(session).identity;
    return {std::move(worker), held_render(session, lease_id)};
}

bool Coordinator::renew(const std::string& session, uint64_t lease_id) {
    const auto [worker, slot] = holder_and_render(session, lease_id);
    if (!slot) return false;
    std::lock_guard render(slot->mutex);
    return slot->session->renew(lease_id, worker,
                                RenderSession::Clock::now() + options_.lease_time);
}

bool Coordinator::abandon(const std::string& session, uint64_t lease_id) {
    const auto [worker, slot] = holder_and_render(session, lease_id);
    if (!slot) return false;
    {
        std::lock_guard render(slot->mutex);
        if (!slot->session->abandon(lease_id, worker)) return false;
    }
    std::lock_guard lock(mutex_);
    leases_.end(lease_id);
    changed();
    return true;
}

bool Coordinator::fail(const std::string& session, uint64_t lease_id,
                       const std::string& reason) {
    std::string worker, worker_name;
    SlotPtr slot;
    std::shared_ptr<const std::set<std::string>> alive;
    FailurePolicy policy;
    {
        std::lock_guard lock(mutex_);
        const WorkerRegistry::Link caller = registry_.link_of(session);
        worker = caller.identity;
        worker_name = caller.worker;
        slot = held_render(session, lease_id);
        alive = registry_.alive_identities();
        policy = failure_policy_of(caller);
    }
    if (!slot) return false;
    bool render_failed = false;
    {
        std::lock_guard render(slot->mutex);
        RenderSession& s = *slot->session;
        if (!s.fail_job(lease_id, worker, reason, *alive, policy)) return false;
        if (s.failures_of(worker) == options_.failure_policy.blocklist_after)
            events_.on_render(EventKind::WorkerBlocklisted, s.id(),
                              {log_text("worker", worker_name), log_text("host", worker),
                               log_text("reason", reason)});
        render_failed = s.state() == RenderState::Failed;
        if (render_failed) log_farm_error(s.id() + " failed: " + s.error());
    }
    std::lock_guard lock(mutex_);
    leases_.end(lease_id);
    registry_.note_failure(worker_name);
    // The render's other leases ended with it.
    if (render_failed) forget_ended_leases({}, {slot->session->id()});
    changed();
    return true;
}

bool Coordinator::knows_worker(const std::string& name) {
    std::lock_guard lock(mutex_);
    return registry_.knows(name);
}

size_t Coordinator::leases_out() {
    std::lock_guard lock(mutex_);
    return leases_.size();
}

uint64_t Coordinator::samples_merged() const { return samples_merged_; }

uint64_t Coordinator::store_write_failures() const { return archive_.write_failures(); }

std::map<RenderState, uint64_t> Coordinator::render_counts() {
    // The store is read off the coordinator's lock, as list() reads it.
    if (archive_.keeps_records()) return archive_.counts_by_state();
    // A session is Running from its submission; it counts as Queued while no job of it
    // has been leased, as info() and list() show it.
    std::vector<std::pair<SlotPtr, bool>> slots;  // with whether it waits in the queue
    {
        std::lock_guard lock(mutex_);
        for (SlotPtr& slot : slots_in_order())
            slots.emplace_back(slot, queue_.position(slot->session->id()) > 0);
    }
    std::map<RenderState, uint64_t> counts;
    for (const auto& [slot, queued] : slots) {
        std::lock_guard render(slot->mutex);
        const RenderState state = slot->session->state();
        ++counts[queued && state == RenderState::Running ? RenderState::Queued : state];
    }
    return counts;
}

double Coordinator::round_end_seconds() {
    std::lock_guard lock(mutex_);
    return round_end_seconds_;
}

double Coordinator::round_end_wait_seconds() {
    std::lock_guard lock(mutex_);
    return round_end_wait_seconds_;
}

double Coordinator::round_end_cpu_seconds() {
    std::lock_guard lock(mutex_);
    return round_end_cpu_seconds_;
}

uint64_t Coordinator::rounds_ended() {
    std::lock_guard lock(mutex_);
    return rounds_ended_;
}

size_t Coordinator::worker_sessions() {
    std::lock_guard lock(mutex_);
    return registry_.links();
}

void Coordinator::forget_ended_leases(const std::vector<uint64_t>& ended,
                                      const std::set<std::string>& finished) {
    leases_.forget_ended(ended, finished, [this](const std::string& id) {
        return sessions_.count(id) > 0;
    });
}

std::vector<WorkerStatus> Coordinator::workers() {
    // Each lease keeps its label, so no render's lock is taken.
    std::lock_guard lock(mutex_);
    std::map<std::string, std::vector<std::string>> leases;  // worker -> "render/job"
    for (const auto& [id, lease] : leases_.all()) {
        const WorkerRegistry::Link* link = registry_.find_link(lease.link);
        if (lease.render.empty() || !link) continue;
        leases[link->worker].push_back(lease.label);
    }
    return registry_.statuses(std::move(leases));
}

std::string Coordinator::storage_warning() {
    std::lock_guard lock(mutex_);
    return archive_.warning();
}

void Coordinator::tick() {
    // Leases past their deadline go back to their renders' queues, under each render's
    // lock; then, under the coordinator's, they and the leases of renders finished
    // since are gone for good.
    std::vector<SlotPtr> slots;
    {
        std::lock_guard lock(mutex_);
        slots = slots_in_order();
    }
    const auto now = RenderSession::Clock::now();
    std::vector<uint64_t> expired;
    std::set<std::string> finished;
    bool opened_ahead = false;  // a round planned ahead can be leased now
    for (const SlotPtr& slot : slots) {
        std::lock_guard render(slot->mutex);
        if (slot->session->finished()) {
            finished.insert(slot->session->id());
        } else {
            for (const uint64_t lease : slot->session->expire(now))
                expired.push_back(lease);
            opened_ahead = slot->session->announce_next_round() || opened_ahead;
        }
    }
    bool retention_due = false, wal_due = false;
    {
        std::lock_guard lock(mutex_);
        bool any = !expired.empty() || opened_ahead;
        forget_ended_leases(expired, finished);
        const int64_t wall = unix_millis_now();
        // Rows of workers long silent are swept at the first tick, then about once a
        // minute.
        if (registry_.tick(wall, ticks_ % 300 == 0)) any = true;
        if (any) changed();
        ++ticks_;
        wal_due = ticks_ % 50 == 0;
        // At the first tick, then once a minute, or a quarter of keep_finished when that
        // is shorter (at least a second), so that a render is kept about as long as
        // asked.
        const auto now_steady = std::chrono::steady_clock::now();
        const auto every = std::clamp<std::chrono::milliseconds>(
            options_.keep_finished / 4, std::chrono::seconds(1), std::chrono::minutes(1));
        if (options_.keep_finished.count() > 0 &&
            (ticks_ == 1 || now_steady - last_retention_ >= every)) {
            retention_due = true;
            last_retention_ = now_steady;
        }
    }
    archive_.tick(wal_due);  // every ~10 s, the WAL too
    // Outside the lock: deleting a render's files can take a while.
    if (retention_due) {
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
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
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
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
    if (slot) {
        std::lock_guard render(slot->mutex);
        return slot->session->strategy().buckets();
    }
    return archive_.stored_buckets(id);
}

// ---- Memory: the budget, and finished renders leaving it ----

uint64_t Coordinator::memory_in_use_locked() const {
    uint64_t total = reserved_memory_;
    for (const auto& [id, slot] : sessions_) {
        const RenderSpec& spec = slot->session->spec();  // never changes: no render lock
        total +=
            render_memory_estimate(spec.width, spec.height, spec.reference.has_value());
    }
    return total;
}

uint64_t Coordinator::memory_in_use() {
    std::lock_guard lock(mutex_);
    return memory_in_use_locked();
}

uint64_t Coordinator::reference_allowance(uint32_t width, uint32_t height) {
    if (options_.memory_limit == 0) return 0;
    const uint64_t needed = render_memory_estimate(width, height, true);
    std::lock_guard lock(mutex_);
    const uint64_t in_use = memory_in_use_locked();
    if (needed > options_.memory_limit || in_use > options_.memory_limit - needed)
        throw MemoryBudgetError(needed, in_use, sessions_.size(), options_.memory_limit);
    const uint64_t rgb = uint64_t(width) * height * 3 * sizeof(float);
    return options_.memory_limit - in_use - needed + rgb;
}

size_t Coordinator::sessions_in_memory() {
    std::lock_guard lock(mutex_);
    return sessions_.size();
}

void Coordinator::drop_scene_if_unused(const std::string& hash) {
    for (const auto& [id, slot] : sessions_)
        if (slot->session->scene_hash() == hash) return;  // never changes: no render lock
    scenes_.erase(hash);  // workers still tracing it fetch it from the store
}

size_t Coordinator::scenes_in_memory() {
    std::lock_guard lock(mutex_);
    return scenes_.size();
}

void Coordinator::evict(const std::string& id) {
    const auto it = sessions_.find(id);
    // Finished sessions change no more, so this reads its state without its lock.
    if (it == sessions_.end() || !it->second->session->finished()) return;
    const std::string hash = it->second->session->scene_hash();
    sessions_.erase(it);  // a call that found the slot before keeps it until it is done
    drop_scene_if_unused(hash);
    order_.erase(std::remove(order_.begin(), order_.end(), id), order_.end());
    queue_.leave(id);
    events_.forget(id);  // its events are the store's to serve now
    // Leases of a cancelled render that workers still hold: their results are now
    // answered as unknown, which is what they were (ignored) before.
    leases_.forget_render(id);
    // glibc keeps freed pages of its arenas for reuse; a finished render's buffers are
    // tens of megabytes, and given back they let the coordinator's size follow its live
    // renders rather than its busiest moment.
    malloc_trim(0);
    changed();
}

}  // namespace aliquot
