#include "coordinator.h"

#include <fcntl.h>
#include <malloc.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <stdexcept>

#include "bands.h"
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
        {"strategy", spec.strategy},     {"has_reference", spec.reference.has_value()},
        {"name", spec.name}};
}

// The outcome's key, in the store only, for what a render's end records besides it.
constexpr const char* kFinalKey = "_final";

double thread_cpu_seconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

void log_error(const std::string& what) {
    std::fprintf(stderr, "coordinator: %s\n", what.c_str());
}

// The data directory holds every scene, image and checkpoint of the farm's users: only
// the coordinator's user may read it, whatever the umask (docs/SECURITY.md, "Files").
void make_private_dir(const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir);
    std::filesystem::permissions(dir, std::filesystem::perms::owner_all);
}

// Creates `path` empty with mode 0600 (or makes an existing file 0600), so that a write
// that then opens it with the umask's mode (write_exr) keeps it private from the start.
void create_private_file(const std::filesystem::path& path) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0600);
    if (fd < 0)
        throw std::runtime_error("cannot create " + path.string() + ": " +
                                 std::strerror(errno));
    const bool ok = ::fchmod(fd, 0600) == 0;
    const int error = errno;
    ::close(fd);
    if (!ok)
        throw std::runtime_error("cannot make " + path.string() +
                                 " private: " + std::strerror(error));
}

// The host a network peer called from, without its port ("ipv4:10.0.0.5:41234" ->
// "ipv4:10.0.0.5", "ipv6:%5B::1%5D:41234" -> "ipv6:%5B::1%5D"): what failures count
// against. The port is the caller's to choose with each connection; the host is not.
std::string host_of_peer(const std::string& peer) {
    if (peer.empty()) return "unknown peer";
    const bool ip = peer.rfind("ipv4:", 0) == 0 || peer.rfind("ipv6:", 0) == 0;
    const size_t colon = peer.rfind(':');
    if (!ip || colon <= 5 || colon + 1 == peer.size()) return peer;
    for (size_t i = colon + 1; i < peer.size(); ++i)
        if (!std::isdigit(static_cast<unsigned char>(peer[i]))) return peer;
    return peer.substr(0, colon);
}

// A host no session has (peers are "ipv4:...", "ipv6:...", "unix:...", in-process
// workers "process:NAME"): added to the live hosts a failure is counted with, it makes
// RenderSession see another host that could take the job, so that failures alone on
// one host never fail the render (fail_on_fewer_hosts). Jobs are issued with the true
// set.
constexpr const char* kAnotherHost = "\x01another host";

}  // namespace

Coordinator::Coordinator(CoordinatorOptions options) : options_(std::move(options)) {
    if (!options_.data_dir.empty()) {
        make_private_dir(options_.data_dir);
        make_private_dir(options_.data_dir / "renders");
        store_ = std::make_unique<RunStore>(options_.data_dir);
        events_.record_to(store_.get(), &backlog_);
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
    for (const std::string& id : store_->deleted_render_ids()) consider(id);
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

Coordinator::SlotPtr Coordinator::slot_of(const std::string& id) const {
    const auto it = sessions_.find(id);
    return it == sessions_.end() ? nullptr : it->second;
}

std::vector<Coordinator::SlotPtr> Coordinator::slots_in_order() const {
    std::vector<SlotPtr> out;
    out.reserve(order_.size());
    for (const std::string& id : order_) out.push_back(sessions_.at(id));
    return out;
}

std::vector<Coordinator::SlotPtr> Coordinator::slots_by_priority() const {
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
    s->on_round = [this, raw](RenderSession&, const RoundSummary& round) {
        record_round(*raw, round);
    };
    s->on_finished = [this, raw](RenderSession&) { record_end(*raw); };
    slot->session = std::move(session);
    slot->priority = s->spec().priority;
    slot->number = submissions_++;
    order_.push_back(s->id());
    sessions_[s->id()] = std::move(slot);
    alive_workers();  // brings alive_cores_ up to date: the first round is cut for them
    s->set_worker_cores(alive_cores_);
    s->start();
    const bool waits = queued && s->state() == RenderState::Running;
    if (waits) queue_.add(s->id(), raw->priority, raw->number);  // running at its lease
    if (store_ && s->state() == RenderState::Running) {
        if (!waits)
            backlog_.submit("record " + s->id() + " as running", [this, id = s->id()] {
                store_->update_render_state(id, RenderState::Running, "",
                                            unix_millis_now());
            });
        prepare_checkpoint_copy(*raw);
    }
    changed();
}

void Coordinator::note_started(const std::string& id) {
    if (store_)
        backlog_.submit("record " + id + " as running", [this, id] {
            store_->update_render_state(id, RenderState::Running, "", unix_millis_now());
        });
    events_.on_render(EventKind::Started, id);
}

// The first checkpoint's copy went into fresh pages at the first round's end, under the
// render's lock: 80-100 ms of the kernel zeroing 150 MB at 1920x1080, once a render but a
// third of each round end for a render of two rounds (docs/PERFORMANCE.md). The backlog's
// thread allocates it instead, touching every page, off every lock; a round end that
// comes first allocates it as before.
void Coordinator::prepare_checkpoint_copy(RenderSlot& slot) {
    const RenderSpec& spec = slot.session->spec();
    backlog_.submit(
        "prepare the checkpoint copy of " + slot.session->id(),
        [width = spec.width, height = spec.height, weak = slot.weak_from_this()] {
            const auto wanted = [&](const SlotPtr& s) {
                std::lock_guard lock(s->mutex);
                return !s->checkpoint_copy && s->session->state() == RenderState::Running;
            };
            if (const SlotPtr s = weak.lock(); !s || !wanted(s)) return;
            auto copy = std::make_shared<CheckpointCopy>();
            try {
                copy->cp.merged = Accumulator(width, height);  // zeroed: pages touched
            } catch (const std::bad_alloc&) {
                return;  // the round end tries when a checkpoint is due
            }
            if (const SlotPtr s = weak.lock()) {
                std::lock_guard lock(s->mutex);
                if (!s->checkpoint_copy && s->session->state() == RenderState::Running)
                    s->checkpoint_copy = copy;
            }
        });
}

void Coordinator::record_round(RenderSlot& slot, const RoundSummary& round) {
    RenderSession& r = *slot.session;
    events_.on_render(EventKind::RoundEnded, r.id(), round_fields(round));
    slot.round_history.push_back(round);  // for rounds(): see the end of this file
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
        // The layout is compared as it is, and made JSON only when it changed: building
        // and printing adaptive's 8160 buckets twice each round was most of this call
        // (~3.5 ms a round end at 1920x1080).
        const std::vector<Bucket> buckets = r.strategy().buckets();
        std::vector<BucketShape> shape(buckets.size());
        for (size_t k = 0; k < buckets.size(); ++k)
            shape[k] = {buckets[k].rect, buckets[k].converged};
        if (!buckets.empty() && shape != slot.bucket_shape) {
            nlohmann::json stored = nlohmann::json::array();
            for (const Bucket& b : buckets)
                stored.push_back({b.rect.x, b.rect.y, b.rect.width, b.rect.height,
                                  b.error, b.converged});
            rec.buckets_json = stored.dump();
            slot.bucket_shape = std::move(shape);
        }
        rec.created_at = unix_millis_now();
        // The round is recorded before the checkpoint that includes it: a crash
        // between the two re-runs the round, and recording it again is a no-op.
        backlog_.submit("record round " + std::to_string(round.index) + " of " + r.id(),
                        [this, rec] { store_->add_round(rec); });
        queue_checkpoint(slot, round);
    } catch (const std::exception& e) {
        // The render goes on; the next round's checkpoint tries again.
        log_error("cannot checkpoint round " + std::to_string(round.index) + " of " +
                  r.id() + ": " + e.what());
    }
}

// Called under the render's lock, after the round's record is queued; may throw (the
// caller logs).
void Coordinator::queue_checkpoint(RenderSlot& slot, const RoundSummary& round) {
    RenderSession& r = *slot.session;
    CheckpointTiming& timing = slot.checkpoint;
    // A strategy holding a round it planned before this round's results is restored
    // from these buffers with that round's counts (made by now: the round end waited for
    // its plan). uniform's round ahead follows from its state: nothing to keep.
    const bool holds = r.strategy().holds_planned_round();
    const std::vector<uint32_t>* planned =
        holds ? r.strategy().round_planned_ahead() : nullptr;
    if (holds && !planned) return;
    if (!timing.in_flight &&
        checkpoint_due(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - timing.ended)
                .count(),
            timing.cost_seconds)) {
        // A copy of the buffers, taken here (far cheaper than writing them), is
        // written by the backlog's thread after the round's record, outside the
        // lock. One copy per render waits at a time: a due checkpoint meanwhile
        // is skipped, and the next round's tries again.
        if (!slot.checkpoint_copy)
            slot.checkpoint_copy = std::make_shared<CheckpointCopy>();
        const std::shared_ptr<CheckpointCopy> copy = slot.checkpoint_copy;
        copy->cp.merged.copy_from(r.merged());  // reuses the memory, copies in bands
        copy->cp.strategy_state = r.strategy().save_state();
        if (planned)
            copy->cp.planned_round.assign(planned->begin(), planned->end());
        else
            copy->cp.planned_round.clear();
        copy->cp.rounds_done = r.rounds_done();
        copy->cp.seconds = round.seconds;
        copy->saved = false;
        timing.in_flight = true;
        // The copy stays the backlog's until the write below has run to its end (the
        // store's row too, which a full disk retries): only then may the next round's
        // checkpoint reuse it.
        backlog_.submit(
            "record the progress of " + r.id(),
            [this, id = r.id(), samples = int64_t(round.samples_total), copy,
             state = copy->cp.strategy_state.dump(), weak = slot.weak_from_this()] {
                if (!copy->saved) {
                    const auto start = std::chrono::steady_clock::now();
                    try {
                        save_checkpoint(render_dir(id) / "checkpoint.bin", copy->cp);
                        copy->saved = true;
                        copy->written = std::chrono::steady_clock::now();
                        copy->write_seconds =
                            std::chrono::duration<double>(copy->written - start).count();
                    } catch (const std::exception& e) {
                        // The render goes on; the next round's checkpoint tries
                        // again.
                        log_error("cannot checkpoint " + id + ": " + e.what());
                    }
                }
                // Throws on a full disk: retried, without writing the file again.
                if (copy->saved) store_->update_render_progress(id, samples, state);
                if (const SlotPtr slot = weak.lock()) {
                    std::lock_guard lock(slot->mutex);
                    slot->checkpoint.in_flight = false;
                    if (copy->saved) {
                        slot->checkpoint.ended = copy->written;
                        slot->checkpoint.cost_seconds = copy->write_seconds;
                    }
                }
            });
    }
}

void Coordinator::record_end(RenderSlot& slot) {
    RenderSession& r = *slot.session;
    events_.on_render(end_event(r.state()), r.id(), end_fields(r));
    if (!store_) return;  // the embedded render keeps its session: no disk to read
    // The session stays in memory until this is written, so a retry finds its
    // buffers; then this write drops it. A finished session changes no more, so the
    // backlog's thread reads it without the lock; only this write removes it.
    backlog_.submit("record the end of " + r.id(), [this, id = r.id(), done = &r] {
        create_private_file(render_dir(id) / "image.exr");
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
        // mkdir is the claim: an existing directory is some earlier render's, never to
        // be overwritten, so its number is skipped. 0700 whatever the umask.
        if (!store_) return id_text;
        if (::mkdir(render_dir(id_text).c_str(), 0700) == 0) return id_text;
        if (errno != EEXIST)
            throw std::runtime_error("cannot create " + render_dir(id_text).string() +
                                     ": " + std::strerror(errno));
    }
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
        id = claim_render_id();
        // Counted until the session is attached, so that submissions meanwhile see it.
        reserved_memory_ += needed;
    }
    // Building the session (its buffers) and writing its record and reference happen
    // off the lock: a 1920x1080 reference is 24 MB to write.
    try {
        const int64_t created = unix_millis_now();
        auto session = std::make_unique<RenderSession>(id, spec, created);
        if (store_) {
            store_->put_scene(hash, spec.scene_name, spec.scene_json, created);
            RenderRecord rec;
            rec.id = id;
            rec.scene_hash = hash;
            rec.spec_json = spec_json(spec).dump();
            rec.created_at = created;
            rec.samples_planned = int64_t(session->samples_planned());
            rec.priority = spec.priority;
            if (spec.reference) rec.reference_path = store_reference(*spec.reference);
            store_->create_render(rec);
            recorded = true;
        }
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
        // A submission that failed (a full disk) leaves no empty directory behind: one
        // per refused submission would pile up, each a render id skipped. A render
        // whose row was written keeps its directory, as the row points to it.
        if (store_ && !recorded) {
            std::error_code ignored;
            std::filesystem::remove_all(render_dir(id), ignored);
        }
        throw;
    }
    return id;
}

std::string Coordinator::store_reference(const Image& ref) const {
    // Content-addressed: a study judges hundreds of renders against one reference, which
    // is then written once, not once per render. Written to a temporary name and renamed,
    // so that two submissions of the same reference at once never read a half-written
    // file.
    const std::string key = content_hash(std::string(
        reinterpret_cast<const char*>(ref.rgb.data()), ref.rgb.size() * sizeof(float)));
    const auto path = options_.data_dir / "references" /
                      (key + "-" + std::to_string(ref.width) + "x" +
                       std::to_string(ref.height) + ".exr");
    if (!std::filesystem::exists(path)) {
        make_private_dir(path.parent_path());
        Image rgb_only(ref.width, ref.height);
        rgb_only.rgb = ref.rgb;
        const auto partial = path.string() + ".partial-" + random_hex(8);
        try {
            create_private_file(partial);
            write_exr(partial, rgb_only);
            std::filesystem::rename(partial, path);
        } catch (...) {
            std::error_code ignored;  // a full disk: nothing half-written stays
            std::filesystem::remove(partial, ignored);
            throw;
        }
    }
    return path.string();
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
            spec.priority = int32_t(rec.priority);
            spec.name = j.value("name", "");
            auto session = std::make_unique<RenderSession>(rec.id, spec, rec.created_at);
            if (auto cp = load_checkpoint(render_dir(rec.id) / "checkpoint.bin"))
                session->restore(std::move(cp->merged), cp->strategy_state,
                                 cp->rounds_done, cp->seconds,
                                 std::move(cp->planned_round));
            std::lock_guard lock(mutex_);  // the backlog's thread may evict meanwhile
            scenes_[rec.scene_hash] = spec.scene_json;
            events_.resume(rec.id);
            events_.on_render(EventKind::Resumed, rec.id);
            attach(std::move(session), rec.state == RenderState::Queued);
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
            out.state = RenderState::Queued;  // the session is ready; no worker has it yet
            out.queue_position = queued_at;
        }
        return out;
    }
    // Not in memory: finished and evicted (its end is in the store), or unknown.
    if (!store_) return std::nullopt;
    const std::optional<RenderRecord> rec = store_->get_render(id);
    if (!rec) return std::nullopt;
    // A render that finished before this coordinator started: what the store remembers.
    RenderInfo info;
    info.id = rec->id;
    const nlohmann::json j = nlohmann::json::parse(rec->spec_json);
    info.scene_name = j.value("scene_name", "");
    info.name = j.value("name", "");
    info.width = j.value("width", 0u);
    info.height = j.value("height", 0u);
    info.seed = j.value("seed", uint64_t(0));
    info.strategy_json = j.value("strategy", nlohmann::json::object()).dump();
    info.method = j.value("strategy", nlohmann::json::object()).value("method", "");
    info.state = rec->state;
    info.priority = int32_t(rec->priority);
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
    if (store_) {
        for (const RenderRecord& r : store_->list_renders(limit)) ids.push_back(r.id);
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
    } else if (!store_ || !store_->get_render(id)) {
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
    } else if (!store_ || !store_->get_render(id)) {
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
    if (store_) {
        // The store is written after the order changes: a full disk delays the record,
        // not the scheduling. A restart before it lands resumes the old priority.
        backlog_.submit("record the priority of " + id, [this, id, priority] {
            store_->set_render_priority(id, priority);
        });
    }
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
        if (!store_) {
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
        while (slot_of(id) && !stopping_ && (failing = backlog_.warning()).empty() &&
               std::chrono::steady_clock::now() < deadline)
            // evict() wakes this; the backlog failing does not, hence the period.
            progress_.wait_for(lock, std::chrono::milliseconds(100));
        if (slot_of(id))
            throw std::runtime_error("render " + id + " is still being written to disk" +
                                     (failing.empty() ? "" : " (" + failing + ")") +
                                     "; try again later");
    }
    if (!store_) return Removal::Unknown;
    const std::optional<RenderRecord> rec = store_->get_render(id);
    if (!rec) return Removal::Unknown;
    if (!is_terminal(rec->state)) return Removal::Unfinished;
    if (!store_->delete_render(id, unix_millis_now()))
        return Removal::Unknown;  // another remove won
    // The rows are gone first: a crash now leaves files nothing points to, never a row
    // pointing to no files.
    std::error_code ec;
    std::filesystem::remove_all(render_dir(id), ec);
    if (ec) log_error("cannot delete the files of " + id + ": " + ec.message());
    if (!rec->reference_path.empty() && !store_->reference_in_use(rec->reference_path))
        std::filesystem::remove(rec->reference_path, ec);
    {
        std::lock_guard lock(mutex_);
        changed();
    }
    return Removal::Removed;
}

size_t Coordinator::remove_expired(int64_t now_ms) {
    if (!store_ || options_.keep_finished.count() <= 0) return 0;
    size_t removed = 0;
    // In batches, so that a first run over years of renders does not list them all.
    for (;;) {
        const std::vector<std::string> ids =
            store_->finished_before(now_ms - options_.keep_finished.count(), 100);
        size_t batch = 0;
        for (const std::string& id : ids) {
            try {
                if (remove(id) == Removal::Removed) ++batch;
            } catch (const std::exception& e) {
                log_error("retention: cannot delete " + id + ": " + e.what());
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
    if (!store_ || !store_->get_render(id)) return std::nullopt;
    const auto path = render_dir(id) / "image.exr";
    if (!std::filesystem::exists(path)) return std::nullopt;
    Image img = read_exr(path);
    if (!aovs) img.extra.clear();
    return img;
}

std::optional<std::filesystem::path> Coordinator::image_file(const std::string& id) {
    {
        std::lock_guard lock(mutex_);
        if (slot_of(id)) return std::nullopt;
    }
    if (!store_ || !store_->get_render(id)) return std::nullopt;
    const auto path = render_dir(id) / "image.exr";
    if (!std::filesystem::exists(path)) return std::nullopt;
    return path;
}

uint64_t Coordinator::wait_for_change(uint64_t seen, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    progress_.wait_for(lock, timeout, [&] { return version_ > seen || stopping_; });
    return version_;
}

void Coordinator::queue_worker_write(std::string what, std::function<void()> write) {
    if (!store_) return;
    // On the backlog's thread, off the coordinator's lock (at 256 workers the samples
    // written every tick were hundreds of SQLite commits under it). Workers' rows are
    // statistics: a write that fails is logged and dropped, never retried in a way that
    // would hold up the renders' records queued behind it.
    backlog_.submit(std::move(what), [write = std::move(write)] {
        try {
            write();
        } catch (const std::exception& e) {
            log_error(e.what());
        }
    });
}

Coordinator::WorkerEntry& Coordinator::touch_worker(const std::string& name) {
    const auto [it, is_new] = workers_.try_emplace(name);
    WorkerEntry& w = it->second;
    const int64_t now = unix_millis_now();
    w.last_seen_ms = now;
    // A worker first heard of here gets its row now, so that marking it lost later has
    // a row to mark. (Since worker sessions, only register_worker meets a new name.)
    if (is_new || w.lost) {
        queue_worker_write("record worker " + name,
                           [this, name, threads = w.threads, now] {
                               store_->upsert_worker(name, threads, now);
                           });
        w.stored_seen_ms = now;
    }
    w.lost = false;
    if (w.registered) set_alive(name, true);
    return w;
}

void Coordinator::set_alive(const std::string& name, bool alive) {
    const bool changed_set = alive ? alive_.insert(name).second : alive_.erase(name) > 0;
    if (changed_set) alive_dirty_ = true;
}

std::shared_ptr<const std::set<std::string>> Coordinator::alive_workers() {
    if (alive_dirty_) {
        std::set<std::string> hosts;
        for (const auto& [session, entry] : worker_sessions_)
            if (alive_.count(entry.worker)) hosts.insert(entry.identity);
        alive_snapshot_ = std::make_shared<const std::set<std::string>>(hosts);
        hosts.insert(kAnotherHost);
        alive_and_another_ = std::make_shared<const std::set<std::string>>(hosts);
        alive_cores_ = 0;
        for (const std::string& name : alive_) alive_cores_ += workers_.at(name).threads;
        alive_dirty_ = false;
    }
    return alive_snapshot_;
}

std::shared_ptr<const std::set<std::string>> Coordinator::alive_for_failures_of(
    const SessionEntry& caller) {
    std::shared_ptr<const std::set<std::string>> alive = alive_workers();
    return caller.trusted || options_.fail_on_fewer_hosts ? alive : alive_and_another_;
}

Coordinator::SessionEntry Coordinator::worker_of_session(const std::string& session) {
    const auto it = worker_sessions_.find(session);
    if (it == worker_sessions_.end())
        throw WorkerUnknown("unknown worker session: register again");
    it->second.last_seen_ms = unix_millis_now();
    touch_worker(it->second.worker);
    return it->second;
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
    alive_dirty_ = true;
}

void Coordinator::forget_worker(const std::string& name) {
    std::erase_if(worker_sessions_,
                  [&name](const auto& kv) { return kv.second.worker == name; });
    set_alive(name, false);
    alive_dirty_ = true;
    workers_.erase(name);
    queue_worker_write("forget worker " + name,
                       [this, name] { store_->forget_worker(name); });
}

void Coordinator::make_room_for_a_worker(const std::string& name) {
    if (workers_.size() < options_.max_workers || workers_.count(name)) return;
    std::set<std::string> holding;  // names holding a lease
    for (const std::string& session : sessions_with_leases())
        if (const auto it = worker_sessions_.find(session); it != worker_sessions_.end())
            holding.insert(it->second.worker);
    auto oldest = workers_.end();
    for (auto it = workers_.begin(); it != workers_.end(); ++it)
        if (!holding.count(it->first) &&
            (oldest == workers_.end() ||
             it->second.last_seen_ms < oldest->second.last_seen_ms))
            oldest = it;
    if (oldest == workers_.end())
        throw TooManyWorkers("the coordinator knows " + std::to_string(workers_.size()) +
                             " workers, each holding a lease; try again later");
    // Its samples not yet recorded go with it; if it is still there, it is told to
    // register again at its next call.
    forget_worker(std::string(oldest->first));
}

void Coordinator::forget_silent_workers(int64_t now_ms) {
    const int64_t after = options_.forget_workers_after.count();
    const std::set<std::string> holding = sessions_with_leases();
    std::set<std::string> named;
    for (auto it = worker_sessions_.begin(); it != worker_sessions_.end();) {
        if (now_ms - it->second.last_seen_ms > after && !holding.count(it->first)) {
            it = worker_sessions_.erase(it);
            alive_dirty_ = true;
        } else {
            named.insert(it->second.worker);
            ++it;
        }
    }
    std::vector<std::string> gone;
    for (const auto& [name, w] : workers_)
        if (w.lost && w.unrecorded == 0 && now_ms - w.last_seen_ms > after &&
            !named.count(name))
            gone.push_back(name);  // a lost worker is not in alive_
    for (const std::string& name : gone) forget_worker(name);
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
    return register_session(name, threads, "process:" + name, true);
}

Registration Coordinator::register_worker(const std::string& name, uint32_t threads,
                                          const std::string& peer) {
    return register_session(name, threads, host_of_peer(peer), false);
}

void Coordinator::describe_worker(const std::string& name, std::string host,
                                  std::string version) {
    std::lock_guard lock(mutex_);
    const auto it = workers_.find(name);
    if (it == workers_.end()) return;
    it->second.host = std::move(host);
    it->second.version = std::move(version);
    changed();
}

Registration Coordinator::register_session(const std::string& name, uint32_t threads,
                                           std::string identity, bool trusted) {
    std::lock_guard lock(mutex_);
    // First: a refused registration adds nothing (the silent session or worker one of
    // these dropped before the other refused stays dropped).
    make_room_for_a_session();
    make_room_for_a_worker(name);
    WorkerEntry& w = touch_worker(name);
    w.threads = threads;
    w.registered = true;
    set_alive(name, true);
    // A full disk must not keep workers out: the row is written again when it returns.
    queue_worker_write("record worker " + name,
                       [this, name, threads, now = w.last_seen_ms] {
                           store_->upsert_worker(name, threads, now);
                       });
    w.stored_seen_ms = w.last_seen_ms;
    // A new session each time; earlier ones of the same name stay valid (their leases are
    // still theirs), so registering with a worker's name neither takes its leases nor
    // locks it out.
    events_.on_worker(EventKind::WorkerRegistered, name,
                      {log_number("threads", int64_t(threads)), log_text("host", identity)});
    std::string session;
    do session = random_hex(16);
    while (worker_sessions_.count(session));
    worker_sessions_.emplace(
        session, SessionEntry{name, std::move(identity), trusted, unix_millis_now()});
    alive_dirty_ = true;
    changed();
    return {session, uint32_t(options_.lease_time.count())};
}

std::optional<LeaseGrant> Coordinator::lease(const std::string& session,
                                             std::chrono::milliseconds wait) {
    std::unique_lock lock(mutex_);
    // Jobs are the session's host's to take: RenderSession counts failures, keeps hosts
    // off jobs and checks lease ownership by this, and the Coordinator checks ownership
    // by session before it asks.
    const std::string worker = worker_of_session(session).identity;
    const auto deadline = std::chrono::steady_clock::now() + wait;
    while (!stopping_) {
        const uint64_t seen = version_;
        const std::vector<SlotPtr> slots = slots_by_priority();
        const std::shared_ptr<const std::set<std::string>> alive = alive_workers();
        const size_t cores = alive_cores_;
        // Reserved now, so that no other lease takes the id while the lock is let go.
        const uint64_t lease_id = new_lease_id();
        lease_render_[lease_id] = {"", session};
        lock.unlock();
        // Renders by priority, in submission order within one; one whose lock is busy (a
        // merge, or a round's end) is passed over at first and waited for only when no
        // other render has a job, so one render's round end holds up no other render's
        // workers.
        std::optional<LeaseGrant> grant;
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
            if (job)
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
            lease_render_[lease_id] = {grant->render_id, session};
            if (queue_.leave(grant->render_id)) note_started(grant->render_id);
            changed();
            return grant;
        }
        lease_render_.erase(lease_id);
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
    SessionEntry caller;
    SlotPtr slot;
    std::shared_ptr<const std::set<std::string>> alive;
    size_t cores = 0;
    {
        std::lock_guard lock(mutex_);
        caller = worker_of_session(session);
        const auto it = lease_render_.find(lease_id);
        if (it == lease_render_.end() || it->second.render.empty())
            return {CompleteStatus::Ignored, "unknown, expired or already merged lease"};
        // Someone else's lease: refused before anything is looked at, and it stays with
        // its holder, whose own result still merges.
        if (it->second.session != session)
            return {CompleteStatus::Ignored, "not your lease"};
        slot = slot_of(it->second.render);
        lease_render_.erase(it);  // whatever the outcome, this lease has ended
        if (!slot) return {CompleteStatus::Ignored, "the render is no longer here"};
        alive = alive_for_failures_of(caller);  // a rejected result counts as a failure
        cores = alive_cores_;
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
        outcome = s.complete(lease_id, caller.identity, result, *alive,
                             options_.failure_policy);
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
        // The worker may have been forgotten meanwhile (it was silent for long): its
        // counts go with it.
        if (const auto w_it = workers_.find(caller.worker); w_it != workers_.end()) {
            WorkerEntry& w = w_it->second;
            const uint64_t samples = result.total_samples();
            w.samples += samples;
            // A worker's own clock: a NaN or a near-zero time would poison the smoothed
            // rate.
            if (std::isfinite(result.wall_seconds) && result.wall_seconds >= 1e-3) {
                // Per-thread rate of this job, times the worker's threads, smoothed.
                const double rate =
                    double(samples) / result.wall_seconds * std::max(w.threads, 1u);
                w.rate = w.rate == 0 ? rate : 0.8 * w.rate + 0.2 * rate;
            }
            w.unrecorded += samples;  // written by tick(), not once per merged job
        }
    }
    changed();
    return outcome;
}

std::optional<std::string> Coordinator::fetch_scene(const std::string& session,
                                                    const std::string& hash) {
    {
        std::lock_guard lock(mutex_);
        worker_of_session(session);
        if (auto it = scenes_.find(hash); it != scenes_.end()) return it->second;
    }
    if (store_)
        if (auto rec = store_->get_scene(hash)) return rec->json;
    return std::nullopt;
}

Coordinator::SlotPtr Coordinator::held_render(const std::string& session,
                                              uint64_t lease_id) {
    // Only the holder's word counts: anyone else's leaves the lease with its holder.
    const auto it = lease_render_.find(lease_id);
    if (it == lease_render_.end() || it->second.session != session) return nullptr;
    return slot_of(it->second.render);
}

std::pair<std::string, Coordinator::SlotPtr> Coordinator::holder_and_render(
    const std::string& session, uint64_t lease_id) {
    std::lock_guard lock(mutex_);
    std::string worker = worker_of_session(session).identity;
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
    lease_render_.erase(lease_id);
    changed();
    return true;
}

bool Coordinator::fail(const std::string& session, uint64_t lease_id,
                       const std::string& reason) {
    std::string worker, worker_name;
    SlotPtr slot;
    std::shared_ptr<const std::set<std::string>> alive;
    {
        std::lock_guard lock(mutex_);
        const SessionEntry caller = worker_of_session(session);
        worker = caller.identity;
        worker_name = caller.worker;
        slot = held_render(session, lease_id);
        alive = alive_for_failures_of(caller);
    }
    if (!slot) return false;
    bool render_failed = false;
    {
        std::lock_guard render(slot->mutex);
        RenderSession& s = *slot->session;
        if (!s.fail_job(lease_id, worker, reason, *alive, options_.failure_policy))
            return false;
        if (s.failures_of(worker) == options_.failure_policy.blocklist_after)
            events_.on_render(EventKind::WorkerBlocklisted, s.id(),
                              {log_text("worker", worker_name), log_text("host", worker),
                               log_text("reason", reason)});
        render_failed = s.state() == RenderState::Failed;
        if (render_failed) log_error(s.id() + " failed: " + s.error());
    }
    std::lock_guard lock(mutex_);
    lease_render_.erase(lease_id);
    if (const auto it = workers_.find(worker_name); it != workers_.end())
        ++it->second.failures;
    // The render's other leases ended with it.
    if (render_failed) forget_ended_leases({}, {slot->session->id()});
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

uint64_t Coordinator::samples_merged() const { return samples_merged_; }

uint64_t Coordinator::store_write_failures() const { return backlog_.failures(); }

std::map<RenderState, uint64_t> Coordinator::render_counts() {
    // The store is read off the coordinator's lock, as list() reads it.
    if (store_) return store_->count_renders_by_state();
    std::vector<SlotPtr> slots;
    {
        std::lock_guard lock(mutex_);
        slots = slots_in_order();
    }
    std::map<RenderState, uint64_t> counts;
    for (const SlotPtr& slot : slots) {
        std::lock_guard render(slot->mutex);
        ++counts[slot->session->state()];
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
    return worker_sessions_.size();
}

void Coordinator::forget_ended_leases(const std::vector<uint64_t>& ended,
                                      const std::set<std::string>& finished) {
    for (const uint64_t lease : ended) lease_render_.erase(lease);
    // An empty render is a lease being issued now (lease()): not ended.
    std::erase_if(lease_render_, [&](const auto& kv) {
        const std::string& render = kv.second.render;
        return !render.empty() && (finished.count(render) || !sessions_.count(render));
    });
}

std::vector<WorkerStatus> Coordinator::workers() {
    // Each render's leases under its own lock, then the workers under the coordinator's.
    std::vector<SlotPtr> slots;
    {
        std::lock_guard lock(mutex_);
        slots = slots_in_order();
    }
    // A session knows its leases by host (the session's identity), "render/job" each:
    // they are the host's workers', which lease_render_ names below.
    using RenderHost = std::pair<std::string, std::string>;
    std::map<RenderHost, std::vector<std::string>> labels;
    for (const SlotPtr& slot : slots) {
        std::lock_guard render(slot->mutex);
        if (slot->session->finished()) continue;
        for (auto& [host, label] : slot->session->leases())
            labels[{slot->session->id(), host}].push_back(std::move(label));
    }
    std::lock_guard lock(mutex_);
    // Each of a host's leases on a render goes to one of its workers holding a lease
    // there. Workers sharing a host may see each other's job numbers (which of them holds
    // which job, RenderSession does not say), never another host's or a count not theirs.
    std::map<std::string, std::vector<std::string>> leases;  // worker -> "render/job"
    for (const auto& [lease, owner] : lease_render_) {
        const auto it = worker_sessions_.find(owner.session);
        if (owner.render.empty() || it == worker_sessions_.end()) continue;
        std::vector<std::string>& left = labels[{owner.render, it->second.identity}];
        if (left.empty()) continue;
        leases[it->second.worker].push_back(std::move(left.back()));
        left.pop_back();
    }
    std::vector<WorkerStatus> out;
    for (const auto& [name, w] : workers_) {
        WorkerStatus st;
        st.name = name;
        st.threads = w.threads;
        if (auto it = leases.find(name); it != leases.end())
            st.leases = std::move(it->second);
        st.state = w.lost ? "lost" : (st.leases.empty() ? "idle" : "busy");
        st.samples_traced = w.samples;
        st.samples_per_second = w.lost ? 0 : w.rate;
        st.last_seen_ms = w.last_seen_ms;
        st.host = w.host;
        st.version = w.version;
        st.failures = w.failures;
        out.push_back(std::move(st));
    }
    return out;
}

std::string Coordinator::storage_warning() {
    std::lock_guard lock(mutex_);
    return backlog_.warning();
}

void Coordinator::tick() {
    backlog_.retry();
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
        // Not a structured binding: the lambdas below copy the name, and C++17 (clang's,
        // for the fuzz build) cannot capture one.
        for (auto& entry : workers_) {
            const std::string& name = entry.first;
            WorkerEntry& w = entry.second;
            if (w.unrecorded > 0) {
                queue_worker_write(
                    "record the samples of " + name,
                    [this, name, samples = int64_t(w.unrecorded), seen = w.last_seen_ms] {
                        store_->record_worker_samples(name, samples, seen);
                    });
                w.unrecorded = 0;
                w.stored_seen_ms = w.last_seen_ms;
            } else if (!w.lost && w.last_seen_ms - w.stored_seen_ms >
                                      options_.forget_workers_after.count() / 4) {
                // An idle worker's row is kept fresh, so that the sweep below takes only
                // workers gone.
                queue_worker_write(
                    "record that " + name + " is still here",
                    [this, name, threads = w.threads, seen = w.last_seen_ms] {
                        store_->upsert_worker(name, threads, seen);
                    });
                w.stored_seen_ms = w.last_seen_ms;
            }
            if (!w.lost && wall - w.last_seen_ms > options_.worker_lost_after.count()) {
                w.lost = true;
                set_alive(name, false);
                any = true;
                events_.on_worker(EventKind::WorkerLost, name,
                                  {log_number("last_seen_ms", w.last_seen_ms)});
                queue_worker_write("record that " + name + " is lost", [this, name] {
                    store_->mark_worker_state(name, "lost");
                });
            }
        }
        forget_silent_workers(wall);
        // Rows of workers silent as long, those of an earlier run of the coordinator
        // included (it remembers no worker across a restart): at the first tick, then
        // about once a minute.
        if (ticks_ % 300 == 0)
            queue_worker_write(
                "forget workers silent since " + std::to_string(wall),
                [this, before = wall - options_.forget_workers_after.count()] {
                    store_->forget_workers_silent_since(before);
                });
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
    // Every ~10 s, outside the lock: keep the WAL from growing without bound. A full disk
    // fails it; the next one tries again.
    if (store_ && wal_due) {
        try {
            store_->checkpoint();
        } catch (const std::exception& e) {
            log_error(e.what());
        }
    }
    // Outside the lock: deleting a render's files can take a while.
    if (retention_due) {
        try {
            remove_expired(unix_millis_now());
        } catch (const std::exception& e) {
            log_error(std::string("retention: ") + e.what());  // tried again next time
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
    SlotPtr slot;
    {
        std::lock_guard lock(mutex_);
        slot = slot_of(id);
    }
    if (slot) {
        std::lock_guard render(slot->mutex);
        std::vector<RoundSummary>& history = slot->round_history;
        // A resumed render's history in memory starts at its checkpoint: fill it in from
        // the store once.
        if (history.size() < slot->session->rounds_done() && store_) {
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
    std::erase_if(lease_render_,
                  [&id](const auto& kv) { return kv.second.render == id; });
    // glibc keeps freed pages of its arenas for reuse; a finished render's buffers are
    // tens of megabytes, and given back they let the coordinator's size follow its live
    // renders rather than its busiest moment.
    malloc_trim(0);
    changed();
}

}  // namespace aliquot
