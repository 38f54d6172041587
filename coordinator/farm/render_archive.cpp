#include "render_archive.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "exr_io.h"
#include "farm_log.h"
#include "secret.h"
#include "store.h"

namespace aliquot {

namespace {

nlohmann::json spec_json(const RenderSpec& spec) {
    return {{"scene_name", spec.scene_name},
            {"width", spec.width},
            {"height", spec.height},
            {"seed", spec.seed},
            {"strategy", spec.strategy},
            {"has_reference", spec.reference.has_value()},
            {"name", spec.name},
            {"aux", spec.aux}};
}

// The outcome's key, in the store only, for what a render's end records besides it.
constexpr const char* kFinalKey = "_final";

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

RoundSummary summary_of(const RoundRecord& rec) {
    RoundSummary r;
    r.index = uint32_t(rec.idx);
    r.samples_in_round = uint64_t(rec.samples_in_round);
    r.samples_total = uint64_t(rec.samples_total);
    r.seconds = rec.seconds;
    r.error_estimate = rec.error_estimate;
    r.error_vs_reference = rec.error_vs_reference.value_or(-1);
    r.mean_bias = rec.mean_bias;
    r.mean_bias_se = rec.mean_bias_se;
    return r;
}

}  // namespace

RenderArchive::RenderArchive(std::filesystem::path data_dir)
    : data_dir_(std::move(data_dir)) {
    if (data_dir_.empty()) return;
    make_private_dir(data_dir_);
    make_private_dir(data_dir_ / "renders");
    store_ = std::make_unique<RunStore>(data_dir_);
    // Checkpoints, images and store writes run on the backlog's thread, in order, under
    // no lock of the coordinator's (a 2048x2048 checkpoint and EXR held it for 1.4 s).
    backlog_.start_writer();
    next_render_number_ = first_free_render_number();
}

RenderArchive::~RenderArchive() { backlog_.stop_writer(); }

uint64_t RenderArchive::first_free_render_number() const {
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
         std::filesystem::directory_iterator(data_dir_ / "renders", ec))
        consider(entry.path().filename().string());
    return next;
}

std::filesystem::path RenderArchive::render_dir(const std::string& id) const {
    return data_dir_ / "renders" / id;
}

std::string RenderArchive::claim_render_id() {
    std::lock_guard lock(ids_mutex_);
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

void RenderArchive::record_submission(const std::string& id, const RenderSpec& spec,
                                      const std::string& scene_hash, int64_t created_ms,
                                      uint64_t samples_planned) {
    if (!store_) return;
    store_->put_scene(scene_hash, spec.scene_name, spec.scene_json, created_ms);
    RenderRecord rec;
    rec.id = id;
    rec.scene_hash = scene_hash;
    rec.spec_json = spec_json(spec).dump();
    rec.created_at = created_ms;
    rec.samples_planned = int64_t(samples_planned);
    rec.priority = spec.priority;
    if (spec.reference) rec.reference_path = store_reference(*spec.reference);
    store_->create_render(rec);
}

void RenderArchive::unclaim(const std::string& id) {
    // A submission that failed (a full disk) leaves no empty directory behind: one per
    // refused submission would pile up, each a render id skipped.
    if (!store_) return;
    std::error_code ignored;
    std::filesystem::remove_all(render_dir(id), ignored);
}

std::string RenderArchive::store_reference(const Image& ref) const {
    // Content-addressed: a study judges hundreds of renders against one reference, which
    // is then written once, not once per render. Written to a temporary name and renamed,
    // so that two submissions of the same reference at once never read a half-written
    // file.
    const std::string key = content_hash(std::string(
        reinterpret_cast<const char*>(ref.rgb.data()), ref.rgb.size() * sizeof(float)));
    const auto path = data_dir_ / "references" /
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

void RenderArchive::resume_unfinished(const std::function<void(Resumed)>& attach) {
    if (!store_) return;
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
            spec.aux = j.value("aux", false);  // records before issue 34 have none
            auto session = std::make_unique<RenderSession>(rec.id, spec, rec.created_at);
            if (auto cp = load_checkpoint(render_dir(rec.id) / "checkpoint.bin"))
                session->restore(std::move(cp->merged), cp->strategy_state,
                                 cp->rounds_done, cp->seconds,
                                 std::move(cp->planned_round), std::move(cp->aux));
            attach(
                {std::move(session), rec.scene_hash, rec.state == RenderState::Queued});
        } catch (const std::exception& e) {
            log_farm_error("cannot resume " + rec.id + ": " + e.what());
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

void RenderArchive::record_running(const std::string& id) {
    if (!store_) return;
    backlog_.submit("record " + id + " as running", [this, id] {
        store_->update_render_state(id, RenderState::Running, "", unix_millis_now());
    });
}

// The first checkpoint's copy went into fresh pages at the first round's end, under the
// render's lock: 80-100 ms of the kernel zeroing 150 MB at 1920x1080, once a render but a
// third of each round end for a render of two rounds (docs/PERFORMANCE.md). The backlog's
// thread allocates it instead, touching every page, off every lock; a round end that
// comes first allocates it as before.
void RenderArchive::prepare_checkpoint_copy(RenderSlot& slot) {
    if (!store_) return;
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
                // Zeroed, so every page is touched here.
                copy->cp.sums.assign(size_t(width) * height, PixelSums{});
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

void RenderArchive::record_round(RenderSlot& slot, const RoundSummary& round) {
    RenderSession& r = *slot.session;
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
        rec.mean_bias = round.mean_bias;
        rec.mean_bias_se = round.mean_bias_se;
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
        log_farm_error("cannot checkpoint round " + std::to_string(round.index) + " of " +
                       r.id() + ": " + e.what());
    }
}

// Called under the render's lock, after the round's record is queued; may throw (the
// caller logs).
void RenderArchive::queue_checkpoint(RenderSlot& slot, const RoundSummary& round) {
    RenderSession& r = *slot.session;
    CheckpointTiming& timing = slot.checkpoint;
    // A strategy holding a round it planned before this round's results is restored
    // from these buffers with that round's counts (made by now: the round end waited for
    // its plan). uniform's round ahead follows from its state: nothing to keep.
    const bool holds = r.strategy().holds_planned_round();
    const std::vector<uint32_t>* planned =
        holds ? r.strategy().round_planned_ahead() : nullptr;
    if (holds && !planned) return;
    // A round that reaches the samples the render plans (an upper bound: strategy.h) is
    // its last: the render's end, queued behind this round's record, records all of it,
    // so a copy and a write of the buffers here would protect nothing for long.
    if (r.samples_planned() > 0 && round.samples_total >= r.samples_planned()) return;
    // Before its first checkpoint here, a render's own seconds and what one is expected
    // to take: none at its first round end, which protects a round or two of work for a
    // copy and a write of the whole buffers (docs/FARM.md). A resumed render's seconds
    // count from its start, so its first round end here checkpoints.
    const auto now = std::chrono::steady_clock::now();
    const bool first = timing.ended == std::chrono::steady_clock::time_point{};
    const double since =
        first ? round.seconds : std::chrono::duration<double>(now - timing.ended).count();
    const double cost =
        first ? expected_checkpoint_seconds(r.merged().pixel_count(), r.aux().kept())
              : timing.cost_seconds;
    if (!timing.in_flight && checkpoint_due(since, cost)) {
        // A copy of the buffers' sums, taken here (no disk, and on every core), is
        // written by the backlog's thread after the round's record, outside the
        // lock. One copy per render waits at a time: a due checkpoint meanwhile
        // is skipped, and the next round's tries again.
        if (!slot.checkpoint_copy)
            slot.checkpoint_copy = std::make_shared<CheckpointCopy>();
        const std::shared_ptr<CheckpointCopy> copy = slot.checkpoint_copy;
        // The sums only (what the file holds), into the copy's memory, in bands.
        copy->cp.copy_buffers(r.merged(), r.aux());
        copy->copy_seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - now).count();
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
                        log_farm_error("cannot checkpoint " + id + ": " + e.what());
                    }
                }
                // Throws on a full disk: retried, without writing the file again.
                if (copy->saved) store_->update_render_progress(id, samples, state);
                if (const SlotPtr slot = weak.lock()) {
                    std::lock_guard lock(slot->mutex);
                    slot->checkpoint.in_flight = false;
                    if (copy->saved) {
                        // Its copy counts: it held the render's lock and took the cores.
                        slot->checkpoint.ended = copy->written;
                        slot->checkpoint.cost_seconds =
                            copy->copy_seconds + copy->write_seconds;
                    }
                }
            });
    }
}

void RenderArchive::record_end(RenderSlot& slot,
                               std::function<void(const std::string&)> written) {
    RenderSession& r = *slot.session;
    if (!store_) return;  // the embedded render keeps its session: no disk to read
    // The session stays in memory until this is written, so a retry finds its
    // buffers; then this write drops it. A finished session changes no more, so the
    // backlog's thread reads it without the lock; only this write removes it.
    backlog_.submit("record the end of " + r.id(), [this, id = r.id(), done = &r,
                                                    written = std::move(written)] {
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
        written(id);
    });
}

void RenderArchive::record_priority(const std::string& id, int32_t priority) {
    if (!store_) return;
    backlog_.submit("record the priority of " + id,
                    [this, id, priority] { store_->set_render_priority(id, priority); });
}

void RenderArchive::complete_history(RenderSlot& slot) {
    std::vector<RoundSummary>& history = slot.round_history;
    // A resumed render's history in memory starts at its checkpoint: fill it in from the
    // store once.
    if (history.size() >= slot.session->rounds_done() || !store_) return;
    std::vector<RoundSummary> all;
    for (const RoundRecord& rec : store_->rounds(slot.session->id()))
        all.push_back(summary_of(rec));
    if (all.size() > history.size()) history = std::move(all);
}

bool RenderArchive::knows(const std::string& id) {
    return store_ && store_->get_render(id).has_value();
}

std::optional<RenderInfo> RenderArchive::stored_info(const std::string& id) {
    if (!store_) return std::nullopt;
    // Not in memory: finished and evicted (its end is in the store), or unknown.
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
        info.mean_bias = last->mean_bias;
        info.mean_bias_se = last->mean_bias_se;
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

std::vector<std::string> RenderArchive::recent_ids(size_t limit) {
    std::vector<std::string> ids;
    if (store_)
        for (const RenderRecord& r : store_->list_renders(limit)) ids.push_back(r.id);
    return ids;
}

std::optional<std::vector<RoundSummary>> RenderArchive::stored_rounds(
    const std::string& id) {
    if (!knows(id)) return std::nullopt;
    std::vector<RoundSummary> out;
    for (const RoundRecord& rec : store_->rounds(id)) out.push_back(summary_of(rec));
    return out;
}

std::optional<std::vector<Bucket>> RenderArchive::stored_buckets(const std::string& id) {
    if (!knows(id)) return std::nullopt;
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

std::optional<Image> RenderArchive::stored_image(const std::string& id, bool aovs) {
    const std::optional<std::filesystem::path> path = image_file(id);
    if (!path) return std::nullopt;
    Image img = read_exr(*path);
    if (!aovs) img.extra.clear();
    return img;
}

std::optional<std::filesystem::path> RenderArchive::image_file(const std::string& id) {
    if (!knows(id)) return std::nullopt;
    const auto path = render_dir(id) / "image.exr";
    if (!std::filesystem::exists(path)) return std::nullopt;
    return path;
}

std::optional<std::string> RenderArchive::stored_scene(const std::string& hash) {
    if (store_)
        if (auto rec = store_->get_scene(hash)) return rec->json;
    return std::nullopt;
}

std::map<RenderState, uint64_t> RenderArchive::counts_by_state() {
    return store_ ? store_->count_renders_by_state() : std::map<RenderState, uint64_t>{};
}

RenderArchive::Deletion RenderArchive::delete_render(const std::string& id) {
    if (!store_) return Deletion::Unknown;
    const std::optional<RenderRecord> rec = store_->get_render(id);
    if (!rec) return Deletion::Unknown;
    if (!is_terminal(rec->state)) return Deletion::Unfinished;
    if (!store_->delete_render(id, unix_millis_now()))
        return Deletion::Unknown;  // another remove won
    // The rows are gone first: a crash now leaves files nothing points to, never a row
    // pointing to no files.
    std::error_code ec;
    std::filesystem::remove_all(render_dir(id), ec);
    if (ec) log_farm_error("cannot delete the files of " + id + ": " + ec.message());
    if (!rec->reference_path.empty() && !store_->reference_in_use(rec->reference_path))
        std::filesystem::remove(rec->reference_path, ec);
    return Deletion::Deleted;
}

std::vector<std::string> RenderArchive::finished_before(int64_t before_ms, size_t limit) {
    return store_ ? store_->finished_before(before_ms, limit)
                  : std::vector<std::string>{};
}

void RenderArchive::queue_worker_write(std::string what, std::function<void()> write) {
    if (!store_) return;
    // On the backlog's thread, off the coordinator's lock (at 256 workers the samples
    // written every tick were hundreds of SQLite commits under it). Workers' rows are
    // statistics: a write that fails is logged and dropped, never retried in a way that
    // would hold up the renders' records queued behind it.
    backlog_.submit(std::move(what), [write = std::move(write)] {
        try {
            write();
        } catch (const std::exception& e) {
            log_farm_error(e.what());
        }
    });
}

void RenderArchive::record_worker(const std::string& name, uint32_t threads,
                                  int64_t seen_ms) {
    queue_worker_write("record worker " + name, [this, name, threads, seen_ms] {
        store_->upsert_worker(name, threads, seen_ms);
    });
}

void RenderArchive::record_worker_samples(const std::string& name, uint64_t samples,
                                          int64_t seen_ms) {
    queue_worker_write("record the samples of " + name, [this, name, samples, seen_ms] {
        store_->record_worker_samples(name, int64_t(samples), seen_ms);
    });
}

void RenderArchive::record_worker_lost(const std::string& name) {
    queue_worker_write("record that " + name + " is lost",
                       [this, name] { store_->mark_worker_state(name, "lost"); });
}

void RenderArchive::forget_worker(const std::string& name) {
    queue_worker_write("forget worker " + name,
                       [this, name] { store_->forget_worker(name); });
}

void RenderArchive::forget_workers_silent_since(int64_t before_ms) {
    queue_worker_write(
        "forget workers silent since " + std::to_string(before_ms),
        [this, before_ms] { store_->forget_workers_silent_since(before_ms); });
}

void RenderArchive::tick(bool wal_due) {
    backlog_.retry();
    // Every ~10 s, off every lock: keep the WAL from growing without bound. A full disk
    // fails it; the next one tries again.
    if (!store_ || !wal_due) return;
    try {
        store_->checkpoint();
    } catch (const std::exception& e) {
        log_farm_error(e.what());
    }
}

}  // namespace aliquot
