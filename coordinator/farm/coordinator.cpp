#include "coordinator.h"

#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "checkpoint.h"
#include "exr_io.h"
#include "scene_loader.h"
#include "secret.h"
#include "store.h"

namespace aliquot {

namespace {

nlohmann::json spec_json(const RenderSpec& spec) {
    return {
        {"scene_name", spec.scene_name}, {"width", spec.width},
        {"height", spec.height},         {"seed", spec.seed},
        {"strategy", spec.strategy},     {"has_reference", spec.reference.has_value()}};
}

// The outcome's key, in the store only, for what a render's end records besides it.
constexpr const char* kFinalKey = "_final";

void log_error(const std::string& what) {
    std::fprintf(stderr, "coordinator: %s\n", what.c_str());
}

}  // namespace

Coordinator::Coordinator(CoordinatorOptions options) : options_(std::move(options)) {
    if (!options_.data_dir.empty()) {
        std::filesystem::create_directories(options_.data_dir / "renders");
        store_ = std::make_unique<RunStore>(options_.data_dir);
        // Checkpoints, images and store writes run on the backlog's thread, in order,
        // not under mutex_ (a 2048x2048 checkpoint and EXR held it for 1.4 s).
        backlog_.start_writer();
        next_render_number_ = first_free_render_number();
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
                log_error(std::string("tick: ") + e.what());
            }
        }
    });
}

Coordinator::~Coordinator() {
    stop();
    if (ticker_.joinable()) ticker_.join();
    tick();  // the workers' last samples reach the store
    // What waits is written before the sessions its writes read go away.
    backlog_.stop_writer();
}

void Coordinator::stop() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    progress_.notify_all();
    work_ready_.notify_all();
}

uint64_t Coordinator::first_free_render_number() const {
    // Numbers come from the store and from the render directories on disk: a database
    // lost or moved aside (as its integrity error advises) must not hand out r-000001
    // again and overwrite that render's image and checkpoint.
    uint64_t next = 1;
    auto consider = [&next](const std::string& id) {
        unsigned long long n = 0;
        char tail = 0;
        if (std::sscanf(id.c_str(), "r-%llu%c", &n, &tail) == 1 && n < UINT64_MAX)
            next = std::max<uint64_t>(next, n + 1);
    };
    for (const RenderRecord& r : store_->list_renders(0)) consider(r.id);
    std::error_code ec;
    for (const auto& entry :
         std::filesystem::directory_iterator(options_.data_dir / "renders", ec))
        consider(entry.path().filename().string());
    return next;
}

std::filesystem::path Coordinator::render_dir(const std::string& id) const {
    return options_.data_dir / "renders" / id;
}

void Coordinator::changed() {
    ++version_;
    progress_.notify_all();
    work_ready_.notify_all();
}

void Coordinator::attach(std::unique_ptr<RenderSession> session) {
    RenderSession* s = session.get();
    s->on_round = [this](RenderSession& r, const RoundSummary& round) {
        record_round(r, round);
    };
    s->on_finished = [this](RenderSession& r) { record_end(r); };
    order_.push_back(s->id());
    sessions_[s->id()] = std::move(session);
    s->start();
    if (store_ && s->state() == RenderState::Running)
        backlog_.submit("record " + s->id() + " as running", [this, id = s->id()] {
            store_->update_render_state(id, RenderState::Running, "", unix_millis_now());
        });
    changed();
}

void Coordinator::record_round(RenderSession& r, const RoundSummary& round) {
    round_history_[r.id()].push_back(round);  // for rounds(): see the end of this file
    if (!store_) return;
    try {
        RoundRecord rec;
        rec.render_id = r.id();
        rec.idx = round.index;
        rec.samples_in_round = int64_t(round.samples_in_round);
        rec.samples_total = int64_t(round.samples_total);
        rec.seconds = round.seconds;
        rec.error_estimate = round.error_estimate;
        if (round.error_vs_reference >= 0)
            rec.error_vs_reference = round.error_vs_reference;
        // Buckets are stored when their layout changes, not every round: Dammertz
        // runs thousands of rounds over hundreds of buckets, and the database would
        // grow by megabytes a render. A round without buckets_json keeps the previous
        // layout.
        nlohmann::json buckets = nlohmann::json::array(), shape = nlohmann::json::array();
        for (const Bucket& b : r.strategy().buckets()) {
            buckets.push_back(
                {b.rect.x, b.rect.y, b.rect.width, b.rect.height, b.error, b.converged});
            shape.push_back(
                {b.rect.x, b.rect.y, b.rect.width, b.rect.height, b.converged});
        }
        std::string& last_shape = bucket_shapes_[r.id()];
        if (!buckets.empty() && shape.dump() != last_shape) {
            rec.buckets_json = buckets.dump();
            last_shape = shape.dump();
        }
        rec.created_at = unix_millis_now();
        // The round is recorded before the checkpoint that includes it: a crash
        // between the two re-runs the round, and recording it again is a no-op.
        backlog_.submit("record round " + std::to_string(round.index) + " of " + r.id(),
                        [this, rec] { store_->add_round(rec); });
        queue_checkpoint(r, round);
    } catch (const std::exception& e) {
        // The render goes on; the next round's checkpoint tries again.
        log_error("cannot checkpoint round " + std::to_string(round.index) + " of " +
                  r.id() + ": " + e.what());
    }
}

// Called under the lock, after the round's record is queued; may throw (the caller logs).
void Coordinator::queue_checkpoint(RenderSession& r, const RoundSummary& round) {
    CheckpointTiming& timing = checkpoint_timing_[r.id()];
    if (!timing.in_flight &&
        checkpoint_due(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - timing.ended)
                .count(),
            timing.cost_seconds)) {
        // A copy of the buffers, taken here (far cheaper than writing them), is
        // written by the backlog's thread after the round's record, outside the
        // lock. One copy per render waits at a time: a due checkpoint meanwhile
        // is skipped, and the next round's tries again.
        struct Pending {
            Checkpoint cp;
            bool saved = false;
        };
        auto pending = std::make_shared<Pending>(Pending{
            {r.merged(), r.strategy().save_state(), r.rounds_done(), round.seconds},
            false});
        timing.in_flight = true;
        backlog_.submit(
            "record the progress of " + r.id(),
            [this, id = r.id(), samples = int64_t(round.samples_total), pending] {
                const auto start = std::chrono::steady_clock::now();
                if (!pending->saved) {
                    try {
                        save_checkpoint(render_dir(id) / "checkpoint.bin", pending->cp);
                        pending->saved = true;
                    } catch (const std::exception& e) {
                        // The render goes on; the next round's checkpoint tries
                        // again.
                        log_error("cannot checkpoint " + id + ": " + e.what());
                    }
                }
                const auto end = std::chrono::steady_clock::now();
                {
                    std::lock_guard lock(mutex_);
                    if (auto it = checkpoint_timing_.find(id);
                        it != checkpoint_timing_.end()) {
                        it->second.in_flight = false;
                        if (pending->saved) {
                            it->second.ended = end;
                            it->second.cost_seconds =
                                std::chrono::duration<double>(end - start).count();
                        }
                    }
                }
                // Throws on a full disk: retried, without writing the file again.
                if (pending->saved)
                    store_->update_render_progress(id, samples,
                                                   pending->cp.strategy_state.dump());
            });
    }
}

void Coordinator::record_end(RenderSession& r) {
    checkpoint_timing_.erase(r.id());
    if (!store_) return;  // the embedded render keeps its session: no disk to read
    // The session stays in memory until this is written, so a retry finds its
    // buffers; then this write drops it. A finished session changes no more, so the
    // backlog's thread reads it without the lock; only this write removes it.
    backlog_.submit("record the end of " + r.id(), [this, id = r.id(), done = &r] {
        write_exr(render_dir(id) / "image.exr", done->image(true));
        // What info() reads back once the session is gone: the final samples, and
        // in the outcome the rays and seconds the store has no column for.
        store_->update_render_progress(id, int64_t(done->merged().total_samples()),
                                       done->strategy().save_state().dump());
        nlohmann::json outcome = done->strategy().outcome();
        if (outcome.is_object())
            outcome[kFinalKey] = {{"rays", done->merged().total_rays()},
                                  {"seconds", done->seconds()}};
        store_->finish_render(id, done->state(), outcome.dump(), unix_millis_now());
        if (!done->error().empty())
            store_->update_render_state(id, done->state(), done->error(),
                                        unix_millis_now());
        std::lock_guard lock(mutex_);
        evict(id);
    });
}

std::string Coordinator::claim_render_id() {
    for (;;) {
        char id_text[32];
        std::snprintf(id_text, sizeof id_text, "r-%06llu",
                      (unsigned long long)next_render_number_++);
        // create_directory is the claim: an existing directory is some earlier render's,
        // never to be overwritten, so its number is skipped.
        if (!store_ || std::filesystem::create_directory(render_dir(id_text)))
            return id_text;
    }
}

std::string Coordinator::submit(RenderSpec spec) {
    validate(spec, options_.max_side);
    // Parse now so a broken scene is the submitter's error, not every worker's.
    parse_submitted_scene(spec.scene_json,
                          spec.scene_name.empty() ? "scene" : spec.scene_name);
    const std::string hash = scene_hash(spec.scene_json);
    std::lock_guard lock(mutex_);
    // Before anything is claimed or written: a refused render leaves no trace.
    const uint64_t needed =
        render_memory_estimate(spec.width, spec.height, spec.reference.has_value());
    const uint64_t in_use = memory_in_use_locked();
    if (options_.memory_limit > 0 &&
        (needed > options_.memory_limit || in_use > options_.memory_limit - needed))
        throw MemoryBudgetError(needed, in_use, sessions_.size(), options_.memory_limit);
    const std::string id = claim_render_id();
    const int64_t created = unix_millis_now();
    scenes_[hash] = spec.scene_json;
    auto session = std::make_unique<RenderSession>(id, spec, created);
    if (store_) {
        store_->put_scene(hash, spec.scene_name, spec.scene_json, created);
        RenderRecord rec;
        rec.id = id;
        rec.scene_hash = hash;
        rec.spec_json = spec_json(spec).dump();
        rec.created_at = created;
        rec.samples_planned = int64_t(session->samples_planned());
        if (spec.reference) {
            // Content-addressed: a study judges hundreds of renders against one
            // reference, which is then written once, not once per render.
            const Image& ref = *spec.reference;
            const std::string key =
                content_hash(std::string(reinterpret_cast<const char*>(ref.rgb.data()),
                                         ref.rgb.size() * sizeof(float)));
            const auto path = options_.data_dir / "references" /
                              (key + "-" + std::to_string(ref.width) + "x" +
                               std::to_string(ref.height) + ".exr");
            if (!std::filesystem::exists(path)) {
                std::filesystem::create_directories(path.parent_path());
                Image rgb_only(ref.width, ref.height);
                rgb_only.rgb = ref.rgb;
                write_exr(path, rgb_only);
            }
            rec.reference_path = path.string();
        }
        store_->create_render(rec);
    }
    attach(std::move(session));
    return id;
}

void Coordinator::resume_unfinished() {
    for (const RenderRecord& rec : store_->unfinished_renders()) {
        try {
            const nlohmann::json j = nlohmann::json::parse(rec.spec_json);
            RenderSpec spec;
            spec.scene_name = j.at("scene_name").get<std::string>();
            spec.width = j.at("width").get<uint32_t>();
            spec.height = j.at("height").get<uint32_t>();
            spec.seed = j.at("seed").get<uint64_t>();
            spec.strategy = j.at("strategy").get<StrategyParams>();
            const std::optional<SceneRecord> scene = store_->get_scene(rec.scene_hash);
            if (!scene) throw std::runtime_error("its scene is missing from the store");
            spec.scene_json = scene->json;
            if (!rec.reference_path.empty())
                spec.reference = read_exr(rec.reference_path);
            scenes_[rec.scene_hash] = spec.scene_json;
            auto session = std::make_unique<RenderSession>(rec.id, spec, rec.created_at);
            if (auto cp = load_checkpoint(render_dir(rec.id) / "checkpoint.bin"))
                session->restore(std::move(cp->merged), cp->strategy_state,
                                 cp->rounds_done, cp->seconds);
            std::lock_guard lock(mutex_);  // the backlog's thread may evict meanwhile
            attach(std::move(session));
        } catch (const std::exception& e) {
            log_error("cannot resume " + rec.id + ": " + e.what());
            backlog_.submit("record that " + rec.id + " cannot resume",
                            [this, id = rec.id, why = std::string(e.what())] {
                                store_->finish_render(id, RenderState::Failed, "{}",
                                                      unix_millis_now());
                                store_->update_render_state(id, RenderState::Failed,
                                                            "cannot resume: " + why,
                                                            unix_millis_now());
                            });
        }
    }
}

RenderInfo Coordinator::info_of(const RenderSession& s) const {
    RenderInfo info;
    info.id = s.id();
    info.scene_name = s.spec().scene_name;
    info.width = s.spec().width;
    info.height = s.spec().height;
    info.seed = s.spec().seed;
    info.method = s.spec().strategy.method;
    info.strategy_json = nlohmann::json(s.spec().strategy).dump();
    info.state = s.state();
    info.error = s.error();
    info.samples_done = s.merged().total_samples();
    info.samples_planned = s.samples_planned();
    info.rays = s.merged().total_rays();
    info.rounds_done = s.rounds_done();
    info.seconds = s.seconds();
    info.samples_per_second =
        info.seconds > 0 ? double(info.samples_done) / info.seconds : 0;
    info.error_estimate = s.error_estimate();
    info.error_vs_reference = s.error_vs_reference();
    info.created_ms = s.created_ms();
    info.outcome_json = s.strategy().outcome().dump();
    return info;
}

std::optional<RenderInfo> Coordinator::info(const std::string& id) {
    std::lock_guard lock(mutex_);
    if (auto it = sessions_.find(id); it != sessions_.end()) return info_of(*it->second);
    if (!store_) return std::nullopt;
    const std::optional<RenderRecord> rec = store_->get_render(id);
    if (!rec) return std::nullopt;
    // A render that finished before this coordinator started: what the store remembers.
    RenderInfo info;
    info.id = rec->id;
    const nlohmann::json j = nlohmann::json::parse(rec->spec_json);
    info.scene_name = j.value("scene_name", "");
    info.width = j.value("width", 0u);
    info.height = j.value("height", 0u);
    info.seed = j.value("seed", uint64_t(0));
    info.strategy_json = j.value("strategy", nlohmann::json::object()).dump();
    info.method = j.value("strategy", nlohmann::json::object()).value("method", "");
    info.state = rec->state;
    info.error = rec->error;
    info.samples_done = uint64_t(rec->samples_done);
    info.samples_planned = uint64_t(rec->samples_planned);
    // Only the last round: the live-update loop lists renders several times a second, and
    // a finished Dammertz render can have thousands of rounds.
    if (const std::optional<RoundRecord> last = store_->last_round(id)) {
        info.rounds_done = uint32_t(last->idx + 1);  // rounds are recorded 0, 1, 2, ...
        info.seconds = last->seconds;
        info.error_estimate = last->error_estimate;
        info.error_vs_reference = last->error_vs_reference.value_or(-1);
    }
    info.samples_per_second =
        info.seconds > 0 ? double(info.samples_done) / info.seconds : 0;
    info.created_ms = rec->created_at;
    info.finished_ms = rec->finished_at.value_or(0);
    info.outcome_json = rec->outcome_json;
    nlohmann::json outcome = nlohmann::json::parse(rec->outcome_json, nullptr, false);
    if (outcome.is_object() && outcome.contains(kFinalKey)) {
        const nlohmann::json final = outcome[kFinalKey];
        info.rays = final.value("rays", uint64_t(0));
        info.seconds = final.value("seconds", info.seconds);
        info.samples_per_second =
            info.seconds > 0 ? double(info.samples_done) / info.seconds : 0;
        outcome.erase(kFinalKey);
        info.outcome_json = outcome.dump();
    }
    return info;
}

std::vector<RenderInfo> Coordinator::list(size_t limit) {
    std::vector<std::string> ids;
    {
        std::lock_guard lock(mutex_);
        if (store_) {
            for (const RenderRecord& r : store_->list_renders(limit)) ids.push_back(r.id);
        } else {
            for (auto it = order_.rbegin(); it != order_.rend() && ids.size() < limit;
                 ++it)
                ids.push_back(*it);
        }
    }
    std::vector<RenderInfo> out;
    for (const std::string& id : ids)
        if (auto i = info(id)) out.push_back(std::move(*i));
    return out;
}

std::optional<RenderInfo> Coordinator::cancel(const std::string& id) {
    {
        std::lock_guard lock(mutex_);
        auto it = sessions_.find(id);
        if (it == sessions_.end()) {
            if (!store_ || !store_->get_render(id)) return std::nullopt;
        } else {
            it->second->cancel();
            changed();
        }
    }
    return info(id);
}

std::optional<Image> Coordinator::image(const std::string& id, bool aovs) {
    std::lock_guard lock(mutex_);
    if (auto it = sessions_.find(id); it != sessions_.end())
        return it->second->image(aovs);
    if (!store_ || !store_->get_render(id)) return std::nullopt;
    const auto path = render_dir(id) / "image.exr";
    if (!std::filesystem::exists(path)) return std::nullopt;
    Image img = read_exr(path);
    if (!aovs) img.extra.clear();
    return img;
}

uint64_t Coordinator::wait_for_change(uint64_t seen, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    progress_.wait_for(lock, timeout, [&] { return version_ > seen || stopping_; });
    return version_;
}

Coordinator::WorkerEntry& Coordinator::touch_worker(const std::string& name) {
    const auto [it, is_new] = workers_.try_emplace(name);
    WorkerEntry& w = it->second;
    const int64_t now = unix_millis_now();
    w.last_seen_ms = now;
    // A worker first heard of here gets its row now, so that marking it lost later has
    // a row to mark. (Since worker sessions, only register_worker meets a new name.)
    if ((is_new || w.lost) && store_) {
        try {
            store_->upsert_worker(name, w.threads, now);
        } catch (const std::exception& e) {
            log_error(e.what());
        }
    }
    w.lost = false;
    if (w.registered) alive_.insert(name);
    return w;
}

const std::string& Coordinator::worker_of_session(const std::string& session) {
    const auto it = worker_sessions_.find(session);
    if (it == worker_sessions_.end())
        throw WorkerUnknown("unknown worker session: register again");
    it->second.last_seen_ms = unix_millis_now();
    touch_worker(it->second.worker);
    return it->second.worker;
}

std::set<std::string> Coordinator::sessions_with_leases() const {
    std::set<std::string> holding;
    for (const auto& [lease, owner] : lease_render_) holding.insert(owner.session);
    return holding;
}

void Coordinator::make_room_for_a_session() {
    if (worker_sessions_.size() < options_.max_worker_sessions) return;
    const std::set<std::string> holding = sessions_with_leases();
    auto oldest = worker_sessions_.end();
    for (auto it = worker_sessions_.begin(); it != worker_sessions_.end(); ++it)
        if (!holding.count(it->first) &&
            (oldest == worker_sessions_.end() ||
             it->second.last_seen_ms < oldest->second.last_seen_ms))
            oldest = it;
    if (oldest == worker_sessions_.end())
        throw TooManyWorkers("the coordinator has " +
                             std::to_string(worker_sessions_.size()) +
                             " worker sessions, each holding a lease; try again later");
    // Its worker, if it is still there, is told to register again at its next call.
    worker_sessions_.erase(oldest);
}

void Coordinator::forget_silent_workers(int64_t now_ms) {
    const int64_t after = options_.forget_workers_after.count();
    const std::set<std::string> holding = sessions_with_leases();
    std::set<std::string> named;
    for (auto it = worker_sessions_.begin(); it != worker_sessions_.end();) {
        if (now_ms - it->second.last_seen_ms > after && !holding.count(it->first)) {
            it = worker_sessions_.erase(it);
        } else {
            named.insert(it->second.worker);
            ++it;
        }
    }
    for (auto it = workers_.begin(); it != workers_.end();) {
        const WorkerEntry& w = it->second;
        if (w.lost && w.unrecorded == 0 && now_ms - w.last_seen_ms > after &&
            !named.count(it->first))
            it = workers_.erase(it);  // its row stays in the store, marked lost (and
                                      // a lost worker is not in alive_)
        else
            ++it;
    }
}

uint64_t Coordinator::new_lease_id() const {
    // Random, so that neither a lease id seen in ListWorkers nor the order they are
    // issued in tells another; a restarted coordinator's ids match a pre-restart lease
    // only with probability (leases out) / 2^64.
    while (true) {
        uint64_t id = 0;
        random_bytes(&id, sizeof id);
        if (id != 0 && !lease_render_.count(id)) return id;
    }
}

Registration Coordinator::register_worker(const std::string& name, uint32_t threads) {
    std::lock_guard lock(mutex_);
    make_room_for_a_session();  // first: a refused registration changes nothing
    WorkerEntry& w = touch_worker(name);
    w.threads = threads;
    w.registered = true;
    alive_.insert(name);
    // A full disk must not keep workers out: the row is written again when it returns.
    if (store_) {
        try {
            store_->upsert_worker(name, threads, unix_millis_now());
        } catch (const std::exception& e) {
            log_error(e.what());
        }
    }
    // A new session each time; earlier ones of the same name stay valid (their leases are
    // still theirs), so registering with a worker's name neither takes its leases nor
    // locks it out.
    std::string session;
    do session = random_hex(16);
    while (worker_sessions_.count(session));
    worker_sessions_.emplace(session, SessionEntry{name, unix_millis_now()});
    changed();
    return {session, uint32_t(options_.lease_time.count())};
}

std::optional<LeaseGrant> Coordinator::lease(const std::string& session,
                                             std::chrono::milliseconds wait) {
    std::unique_lock lock(mutex_);
    const std::string worker = worker_of_session(session);
    const auto deadline = std::chrono::steady_clock::now() + wait;
    while (!stopping_) {
        const std::set<std::string>& alive = alive_workers();
        for (const std::string& id : order_) {
            RenderSession& s = *sessions_[id];
            if (s.state() != RenderState::Running || !s.has_pending()) continue;
            const uint64_t lease_id = new_lease_id();
            std::optional<SampleJob> job = s.issue(
                lease_id, worker, RenderSession::Clock::now() + options_.lease_time,
                alive, options_.failure_policy);
            if (!job) continue;
            lease_render_[lease_id] = {id, session};
            changed();
            return LeaseGrant{
                lease_id,        id,
                s.scene_hash(),  {s.spec().width, s.spec().height, s.spec().seed},
                std::move(*job), uint32_t(options_.lease_time.count())};
        }
        if (work_ready_.wait_until(lock, deadline) == std::cv_status::timeout) break;
    }
    return std::nullopt;
}

CompleteOutcome Coordinator::complete(const std::string& session, uint64_t lease_id,
                                      const SampleJobResult& result) {
    std::lock_guard lock(mutex_);
    const std::string& worker = worker_of_session(session);
    WorkerEntry& w = workers_.at(worker);
    const auto it = lease_render_.find(lease_id);
    if (it == lease_render_.end())
        return {CompleteStatus::Ignored, "unknown, expired or already merged lease"};
    // Someone else's lease: refused before anything is looked at, and it stays with its
    // holder, whose own result still merges.
    if (it->second.session != session) return {CompleteStatus::Ignored, "not your lease"};
    const auto session_it = sessions_.find(it->second.render);
    lease_render_.erase(it);  // whatever the outcome, this lease has ended
    if (session_it == sessions_.end())
        return {CompleteStatus::Ignored, "the render is no longer here"};
    RenderSession& s = *session_it->second;
    const uint32_t rounds_before = s.rounds_done();
    const auto began = std::chrono::steady_clock::now();
    const CompleteOutcome outcome =
        s.complete(lease_id, worker, result, alive_workers(), options_.failure_policy);
    if (s.rounds_done() != rounds_before)  // this result ended a round
        round_end_seconds_ +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - began)
                .count();
    if (outcome.status == CompleteStatus::Merged) {
        const uint64_t samples = result.total_samples();
        w.samples += samples;
        // A worker's own clock: a NaN or a near-zero time would poison the smoothed rate.
        if (std::isfinite(result.wall_seconds) && result.wall_seconds >= 1e-3) {
            // Per-thread rate of this job, times the worker's threads, smoothed.
            const double rate =
                double(samples) / result.wall_seconds * std::max(w.threads, 1u);
            w.rate = w.rate == 0 ? rate : 0.8 * w.rate + 0.2 * rate;
        }
        w.unrecorded += samples;  // written by tick(), not once per merged job
    }
    changed();
    return outcome;
}

std::optional<std::string> Coordinator::fetch_scene(const std::string& session,
                                                    const std::string& hash) {
    std::lock_guard lock(mutex_);
    worker_of_session(session);
    if (auto it = scenes_.find(hash); it != scenes_.end()) return it->second;
    if (store_)
        if (auto rec = store_->get_scene(hash)) return rec->json;
    return std::nullopt;
}

RenderSession* Coordinator::held_render(const std::string& session, uint64_t lease_id) {
    // Only the holder's word counts: anyone else's leaves the lease with its holder.
    const auto it = lease_render_.find(lease_id);
    if (it == lease_render_.end() || it->second.session != session) return nullptr;
    const auto s = sessions_.find(it->second.render);
    return s == sessions_.end() ? nullptr : s->second.get();
}

bool Coordinator::renew(const std::string& session, uint64_t lease_id) {
    std::lock_guard lock(mutex_);
    const std::string& worker = worker_of_session(session);
    RenderSession* s = held_render(session, lease_id);
    return s &&
           s->renew(lease_id, worker, RenderSession::Clock::now() + options_.lease_time);
}

bool Coordinator::abandon(const std::string& session, uint64_t lease_id) {
    std::lock_guard lock(mutex_);
    const std::string& worker = worker_of_session(session);
    RenderSession* s = held_render(session, lease_id);
    if (!s || !s->abandon(lease_id, worker)) return false;
    lease_render_.erase(lease_id);
    changed();
    return true;
}

bool Coordinator::fail(const std::string& session, uint64_t lease_id,
                       const std::string& reason) {
    std::lock_guard lock(mutex_);
    const std::string& worker = worker_of_session(session);
    RenderSession* held = held_render(session, lease_id);
    if (!held || !held->fail_job(lease_id, worker, reason, alive_workers(),
                                 options_.failure_policy))
        return false;
    RenderSession& s = *held;
    lease_render_.erase(lease_id);
    if (s.state() == RenderState::Failed) {
        log_error(s.id() + " failed: " + s.error());
        forget_ended_leases();  // the render's other leases ended with it
    }
    changed();
    return true;
}

bool Coordinator::knows_worker(const std::string& name) {
    std::lock_guard lock(mutex_);
    const auto it = workers_.find(name);
    return it != workers_.end() && it->second.registered;
}

size_t Coordinator::leases_out() {
    std::lock_guard lock(mutex_);
    return lease_render_.size();
}

double Coordinator::round_end_seconds() {
    std::lock_guard lock(mutex_);
    return round_end_seconds_;
}

size_t Coordinator::worker_sessions() {
    std::lock_guard lock(mutex_);
    return worker_sessions_.size();
}

void Coordinator::forget_ended_leases() {
    for (auto it = lease_render_.begin(); it != lease_render_.end();) {
        const auto session = sessions_.find(it->second.render);
        if (session == sessions_.end() || !session->second->holds(it->first))
            it = lease_render_.erase(it);
        else
            ++it;
    }
}

std::vector<WorkerStatus> Coordinator::workers() {
    std::lock_guard lock(mutex_);
    std::vector<WorkerStatus> out;
    for (const auto& [name, w] : workers_) {
        WorkerStatus st;
        st.name = name;
        st.threads = w.threads;
        for (const std::string& id : order_) {
            const RenderSession& s = *sessions_.at(id);
            if (s.finished()) continue;
            for (std::string& l : s.leases_of(name)) st.leases.push_back(std::move(l));
        }
        st.state = w.lost ? "lost" : (st.leases.empty() ? "idle" : "busy");
        st.samples_traced = w.samples;
        st.samples_per_second = w.lost ? 0 : w.rate;
        st.last_seen_ms = w.last_seen_ms;
        out.push_back(std::move(st));
    }
    return out;
}

std::string Coordinator::storage_warning() {
    std::lock_guard lock(mutex_);
    return backlog_.warning();
}

void Coordinator::tick() {
    std::lock_guard lock(mutex_);
    backlog_.retry();
    const auto now = RenderSession::Clock::now();
    bool any = false;
    for (auto& [id, s] : sessions_)
        if (!s->finished() && s->expire(now) > 0) any = true;
    // Expired leases, and those of renders cancelled or finished since: gone for good.
    forget_ended_leases();
    const int64_t wall = unix_millis_now();
    for (auto& [name, w] : workers_) {
        if (store_ && w.unrecorded > 0) {
            try {
                store_->record_worker_samples(name, int64_t(w.unrecorded),
                                              w.last_seen_ms);
            } catch (const std::exception& e) {
                log_error(e.what());
            }
            w.unrecorded = 0;
        }
        if (!w.lost && wall - w.last_seen_ms > options_.worker_lost_after.count()) {
            w.lost = true;
            alive_.erase(name);
            any = true;
            if (store_) {
                try {
                    store_->mark_worker_state(name, "lost");
                } catch (const std::exception& e) {
                    log_error(e.what());
                }
            }
        }
    }
    forget_silent_workers(wall);
    if (any) changed();
    // Every ~10 s: keep the WAL from growing without bound. A full disk fails it; the
    // next one tries again.
    if (store_ && ++ticks_ % 50 == 0) {
        try {
            store_->checkpoint();
        } catch (const std::exception& e) {
            log_error(e.what());
        }
    }
}

// ---- Read-only views for the HTTP API and dashboard ----

namespace {

RoundSummary summary_of(const RoundRecord& rec) {
    RoundSummary r;
    r.index = uint32_t(rec.idx);
    r.samples_in_round = uint64_t(rec.samples_in_round);
    r.samples_total = uint64_t(rec.samples_total);
    r.seconds = rec.seconds;
    r.error_estimate = rec.error_estimate;
    r.error_vs_reference = rec.error_vs_reference.value_or(-1);
    return r;
}

}  // namespace

std::optional<std::vector<RoundSummary>> Coordinator::rounds(const std::string& id) {
    std::lock_guard lock(mutex_);
    const auto live = sessions_.find(id);
    if (live != sessions_.end()) {
        std::vector<RoundSummary>& history = round_history_[id];
        // A resumed render's history in memory starts at its checkpoint: fill it in from
        // the store once.
        if (history.size() < live->second->rounds_done() && store_) {
            std::vector<RoundSummary> all;
            for (const RoundRecord& rec : store_->rounds(id))
                all.push_back(summary_of(rec));
            if (all.size() > history.size()) history = std::move(all);
        }
        return history;
    }
    if (!store_ || !store_->get_render(id)) return std::nullopt;
    std::vector<RoundSummary> out;
    for (const RoundRecord& rec : store_->rounds(id)) out.push_back(summary_of(rec));
    return out;
}

std::optional<std::vector<Bucket>> Coordinator::buckets(const std::string& id) {
    std::lock_guard lock(mutex_);
    if (auto it = sessions_.find(id); it != sessions_.end())
        return it->second->strategy().buckets();
    if (!store_ || !store_->get_render(id)) return std::nullopt;
    std::vector<Bucket> out;
    const std::vector<RoundRecord> recs = store_->rounds(id);
    // The latest layout is in the last round that stored one (see on_round).
    auto last = std::find_if(recs.rbegin(), recs.rend(), [](const RoundRecord& r) {
        return !r.buckets_json.empty();
    });
    if (last == recs.rend()) return out;
    // Rows as on_round writes them: [x, y, width, height, error, converged].
    const nlohmann::json rows = nlohmann::json::parse(last->buckets_json, nullptr, false);
    if (!rows.is_array()) return out;
    for (const nlohmann::json& row : rows) {
        if (!row.is_array() || row.size() < 6 || !row[0].is_number_unsigned() ||
            !row[1].is_number_unsigned() || !row[2].is_number_unsigned() ||
            !row[3].is_number_unsigned())
            continue;
        Bucket b;
        b.rect = {row[0].get<uint32_t>(), row[1].get<uint32_t>(), row[2].get<uint32_t>(),
                  row[3].get<uint32_t>()};
        b.error = row[4].is_number() ? row[4].get<double>() : 0.0;
        b.converged = row[5].is_boolean() ? row[5].get<bool>() : row[5] == 1;
        out.push_back(b);
    }
    return out;
}

// ---- Memory: the budget, and finished renders leaving it ----

namespace {

uint64_t cgroup_memory_limit() {
    // A container's limit (cgroup v2), which sysconf does not see; 0 when there is none.
    std::FILE* f = std::fopen("/sys/fs/cgroup/memory.max", "r");
    if (!f) return 0;
    unsigned long long v = 0;
    const bool number = std::fscanf(f, "%llu", &v) == 1;  // "max" when unlimited
    std::fclose(f);
    return number ? uint64_t(v) : 0;
}

std::string mib(uint64_t bytes) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / (1024.0 * 1024.0));
    return text;
}

}  // namespace

uint64_t default_memory_limit() {
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    uint64_t physical = pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
    if (const uint64_t cg = cgroup_memory_limit();
        cg > 0 && (physical == 0 || cg < physical))
        physical = cg;
    return physical > 0 ? physical / 2 : uint64_t(4) << 30;
}

uint64_t render_memory_estimate(uint32_t width, uint32_t height, bool has_reference) {
    const uint64_t pixels = uint64_t(width) * height;
    uint64_t per_pixel = sizeof(PixelSums)    // the accumulator
                         + sizeof(PixelSums)  // the copy a checkpoint is written from
                         + 12                 // a round's jobs: counts, first indices
                         + 16                 // the round's spp; a strategy's per pixel
                         + 20;                // the final image: RGB, spp, variance
    if (has_reference) per_pixel += 24;  // the reference, and the image compared to it
    return pixels * per_pixel + (uint64_t(1) << 20);  // and a megabyte for the rest
}

MemoryBudgetError::MemoryBudgetError(uint64_t needed_, uint64_t in_use_, size_t renders,
                                     uint64_t limit_)
    : std::runtime_error("not enough memory for this render: it needs " + mib(needed_) +
                         " and the " + std::to_string(renders) +
                         " render(s) in memory use " + mib(in_use_) +
                         " of the coordinator's " + mib(limit_) +
                         " (--memory-limit); wait for renders to finish, or submit a "
                         "smaller one"),
      needed(needed_),
      in_use(in_use_),
      limit(limit_) {}

uint64_t Coordinator::memory_in_use_locked() const {
    uint64_t total = 0;
    for (const auto& [id, s] : sessions_)
        total += render_memory_estimate(s->spec().width, s->spec().height,
                                        s->spec().reference.has_value());
    return total;
}

uint64_t Coordinator::memory_in_use() {
    std::lock_guard lock(mutex_);
    return memory_in_use_locked();
}

size_t Coordinator::sessions_in_memory() {
    std::lock_guard lock(mutex_);
    return sessions_.size();
}

void Coordinator::evict(const std::string& id) {
    const auto it = sessions_.find(id);
    if (it == sessions_.end() || !it->second->finished()) return;
    sessions_.erase(it);
    order_.erase(std::remove(order_.begin(), order_.end(), id), order_.end());
    // Leases of a cancelled render that workers still hold: their results are now
    // answered as unknown, which is what they were (ignored) before.
    std::erase_if(lease_render_,
                  [&id](const auto& kv) { return kv.second.render == id; });
    round_history_.erase(id);
    bucket_shapes_.erase(id);
    checkpoint_timing_.erase(id);
    // glibc keeps freed pages of its arenas for reuse; a finished render's buffers are
    // tens of megabytes, and given back they let the coordinator's size follow its live
    // renders rather than its busiest moment.
    malloc_trim(0);
    changed();
}

}  // namespace aliquot
