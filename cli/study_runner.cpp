#include "study_runner.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <thread>

#include "client.h"
#include "commands.h"
#include "coordinator.h"
#include "error_metric.h"
#include "exr_io.h"
#include "progress_bar.h"
#include "render_proto.h"
#include "scene_loader.h"
#include "store.h"
#include "worker_loop.h"

extern char** environ;

namespace aliquot::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

std::string safe_name(const std::string& s) {
    std::string out;
    for (char c : s)
        out += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.')
                   ? c
                   : '_';
    return out;
}

// Runs this binary with `args` and waits; the child's stderr (its progress bar) stays
// ours.
void run_self(const std::vector<std::string>& args, const std::string& what) {
    const std::string exe = fs::read_symlink("/proc/self/exe").string();
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(exe.c_str()));
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    pid_t pid = 0;
    if (posix_spawn(&pid, exe.c_str(), nullptr, nullptr, argv.data(), environ) != 0)
        throw CommandError("cannot start " + what);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        throw CommandError(what + " failed");
}

// A .npy file (NumPy's own format: a short header, then little-endian float32 data).
void write_npy(const fs::path& path, uint32_t height, uint32_t width, uint32_t channels,
               const std::vector<float>& data) {
    std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" +
                         std::to_string(height) + ", " + std::to_string(width) + ", " +
                         std::to_string(channels) + "), }";
    const size_t total = 10 + header.size() + 1;
    header.append((64 - total % 64) % 64, ' ');
    header += '\n';
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write("\x93NUMPY\x01\x00", 8);
    const uint16_t len = uint16_t(header.size());
    const char len_bytes[2] = {char(len & 0xff), char(len >> 8)};
    out.write(len_bytes, 2);
    out.write(header.data(), std::streamsize(header.size()));
    out.write(reinterpret_cast<const char*>(data.data()),
              std::streamsize(data.size() * 4));
    if (!out) throw CommandError("cannot write " + path.string());
}

// Per pixel: R, G, B of the render, its samples, and |render - reference| averaged over
// RGB.
void write_maps(const fs::path& path, const Image& image, const Image& reference) {
    const Image::Channel* spp = nullptr;
    for (const Image::Channel& c : image.extra)
        if (c.name == "spp") spp = &c;
    std::vector<float> data;
    data.reserve(image.pixel_count() * 5);
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        float err = 0;
        for (size_t c = 0; c < 3; ++c) {
            data.push_back(image.rgb[i * 3 + c]);
            err += std::abs(image.rgb[i * 3 + c] - reference.rgb[i * 3 + c]) / 3.0f;
        }
        data.push_back(spp ? spp->values[i] : 0.0f);
        data.push_back(err);
    }
    write_npy(path, image.height, image.width, 5, data);
}

struct RenderStatus {
    bool known = false;
    std::string state, error;
    uint64_t done = 0, planned = 0;
};

struct Collected {
    std::string local_id;  // the render's record in OUT/data/aliquot.db
    uint64_t samples = 0, rays = 0;
    double seconds = 0;
    std::string outcome_json;
    Image image;  // with the spp channel
};

// Where renders run: the embedded coordinator or a farm.
class Backend {
  public:
    virtual ~Backend() = default;
    virtual std::string origin() const = 0;
    virtual bool parallel() const = 0;
    virtual std::string submit(const RenderSpec& spec,
                               const fs::path& reference_path) = 0;
    virtual RenderStatus status(const std::string& id) = 0;
    virtual Collected collect(const std::string& id, const RenderSpec& spec) = 0;
    virtual void cancel(const std::string& id) = 0;
    // Renders not yet finished that this backend knows of (embedded: resumed ones).
    virtual std::vector<std::string> unfinished() { return {}; }
    virtual void wait() = 0;
};

class EmbeddedBackend final : public Backend {
  public:
    EmbeddedBackend(const fs::path& data_dir, int threads)
        : coordinator_(options(data_dir)),
          workers_(coordinator_,
                   {"study", std::max(threads, 1), std::chrono::milliseconds(200),
                    /*quiet=*/true}),
          pool_([this] { workers_.run(); }) {}
    ~EmbeddedBackend() override {
        workers_.stop();
        coordinator_.stop();
        if (pool_.joinable()) pool_.join();
    }

    std::string origin() const override { return "embedded"; }
    bool parallel() const override { return false; }
    std::string submit(const RenderSpec& spec, const fs::path&) override {
        return coordinator_.submit(spec);
    }
    RenderStatus status(const std::string& id) override {
        RenderStatus s;
        if (const auto info = coordinator_.info(id)) {
            s.known = true;
            s.state = to_string(info->state);
            s.error = info->error;
            s.done = info->samples_done;
            s.planned = info->samples_planned;
        }
        return s;
    }
    Collected collect(const std::string& id, const RenderSpec&) override {
        const RenderInfo info = *coordinator_.info(id);
        Collected c;
        c.local_id = id;
        c.samples = info.samples_done;
        c.rays = info.rays;
        c.seconds = info.seconds;
        c.outcome_json = info.outcome_json;
        c.image = *coordinator_.image(id, true);
        return c;
    }
    void cancel(const std::string& id) override { coordinator_.cancel(id); }
    std::vector<std::string> unfinished() override {
        std::vector<std::string> ids;
        for (const RenderInfo& i : coordinator_.list(0))
            if (!is_terminal(i.state)) ids.push_back(i.id);
        return ids;
    }
    void wait() override {
        seen_ = coordinator_.wait_for_change(seen_, std::chrono::milliseconds(200));
    }

  private:
    static CoordinatorOptions options(const fs::path& data_dir) {
        CoordinatorOptions o;
        o.data_dir = data_dir;
        // Local threads never vanish: long leases, so a slow job is never re-issued.
        o.lease_time = std::chrono::hours(24);
        o.worker_lost_after = std::chrono::hours(24);
        return o;
    }
    Coordinator coordinator_;
    WorkerLoop workers_;
    std::thread pool_;
    uint64_t seen_ = 0;
};

class FarmBackend final : public Backend {
  public:
    FarmBackend(const std::string& address, RunStore& store, const fs::path& data_dir)
        : connection_(address), store_(store), data_dir_(data_dir) {}

    std::string origin() const override { return "farm " + connection_.address(); }
    bool parallel() const override { return true; }
    std::string submit(const RenderSpec& spec, const fs::path& reference_path) override {
        v1::SubmitRequest req;
        req.set_scene_name(spec.scene_name);
        req.set_scene_json(spec.scene_json);
        req.set_width(spec.width);
        req.set_height(spec.height);
        req.set_seed(spec.seed);
        req.set_strategy_json(json(spec.strategy).dump());
        std::ifstream in(reference_path, std::ios::binary);
        std::stringstream bytes;
        bytes << in.rdbuf();
        req.set_reference_exr(bytes.str());
        v1::RenderInfo info;
        connection_.check(
            connection_.stub().Submit(connection_.context(60).get(), req, &info),
            "submit");
        return info.id();
    }
    RenderStatus status(const std::string& id) override {
        v1::GetRenderRequest req;
        req.set_id(id);
        v1::RenderInfo info;
        const grpc::Status st =
            connection_.stub().GetRender(connection_.context().get(), req, &info);
        RenderStatus s;
        if (st.error_code() == grpc::StatusCode::NOT_FOUND) return s;
        connection_.check(st, "status " + id);
        s.known = true;
        s.state = to_string(from_proto(info.state()));
        s.error = info.error();
        s.done = info.samples_done();
        s.planned = info.samples_planned();
        return s;
    }
    Collected collect(const std::string& id, const RenderSpec& spec) override {
        v1::GetRenderRequest req;
        req.set_id(id);
        v1::RenderInfo info;
        connection_.check(
            connection_.stub().GetRender(connection_.context().get(), req, &info),
            "status " + id);
        v1::GetRoundsReply rounds;
        connection_.check(
            connection_.stub().GetRounds(connection_.context(60).get(), req, &rounds),
            "rounds of " + id);
        Collected c;
        // Farm ids are the farm's: prefixed so they never meet an embedded render's id.
        c.local_id = "farm-" + id;
        c.samples = info.samples_done();
        c.rays = info.rays();
        c.seconds = info.seconds();
        c.outcome_json = info.outcome_json();
        const fs::path dir = data_dir_ / "renders" / c.local_id;
        fs::create_directories(dir);
        fetch_image(connection_, id, (dir / "image.exr").string(), true);
        c.image = read_exr(dir / "image.exr");

        // Mirror the render and its rounds into the local database, so one database holds
        // the whole study whichever way it ran.
        const int64_t now = unix_millis_now();
        const std::string hash = scene_hash(spec.scene_json);
        store_.put_scene(hash, spec.scene_name, spec.scene_json, now);
        if (!store_.get_render(c.local_id)) {
            RenderRecord rec;
            rec.id = c.local_id;
            rec.scene_hash = hash;
            rec.spec_json = json{
                {"scene_name", spec.scene_name},
                {"width", spec.width},
                {"height", spec.height},
                {"seed", spec.seed},
                {"strategy", spec.strategy},
                {"farm", origin()},
                {"farm_id", id}}.dump();
            rec.created_at = info.created_ms() ? info.created_ms() : now;
            rec.samples_planned = int64_t(info.samples_planned());
            rec.samples_done = int64_t(info.samples_done());
            store_.create_render(rec);
        }
        for (const v1::RoundInfo& r : rounds.rounds()) {
            RoundRecord rec;
            rec.render_id = c.local_id;
            rec.idx = r.index();
            rec.samples_in_round = int64_t(r.samples_in_round());
            rec.samples_total = int64_t(r.samples_total());
            rec.seconds = r.seconds();
            rec.error_estimate = r.error_estimate();
            if (r.error_vs_reference() >= 0)
                rec.error_vs_reference = r.error_vs_reference();
            rec.created_at = now;
            store_.add_round(rec);
        }
        store_.finish_render(c.local_id, RenderState::Done, c.outcome_json, now);
        return c;
    }
    void cancel(const std::string& id) override {
        v1::GetRenderRequest req;
        req.set_id(id);
        v1::RenderInfo info;
        connection_.stub().Cancel(connection_.context().get(), req, &info);
    }
    void wait() override { std::this_thread::sleep_for(std::chrono::milliseconds(500)); }

  private:
    ClientConnection connection_;
    RunStore& store_;
    fs::path data_dir_;
};

struct Reference {
    fs::path path;
    Image image;
};

std::string reference_key(const StudyRender& r) {
    return r.scene + "|" + std::to_string(r.width) + "x" + std::to_string(r.height);
}

// The scene as the renders need it: a built-in name, or a file relative to the study
// file.
std::string resolve_scene(const std::string& scene, const fs::path& study_file) {
    if (builtin_scene_json(scene)) return scene;
    const fs::path p(scene);
    if (p.is_relative() && !fs::exists(p) && fs::exists(study_file.parent_path() / p))
        return (study_file.parent_path() / p).string();
    return scene;
}

}  // namespace

StudyRunSummary run_study(const StudyDefinition& def, const StudyScale& scale,
                          const StudyRunOptions& opt) {
    const auto started = Clock::now();
    const fs::path data = opt.out / "data";
    fs::create_directories(data / "maps");
    fs::create_directories(data / "references");
    const int threads = opt.threads > 0
                            ? opt.threads
                            : int(std::max(1u, std::thread::hardware_concurrency()));

    std::vector<StudyRender> renders = expand_study(def, scale);
    const std::string id = study_id(def, scale);
    const uint64_t reference_spp =
        scale.reference_spp ? scale.reference_spp : def.reference_spp;

    // References first (each through the shared cache), so a missing one fails early.
    std::map<std::string, Reference> references;
    for (const StudyRender& r : renders) {
        const std::string key = reference_key(r);
        if (references.count(key)) continue;
        const std::string scene = resolve_scene(r.scene, opt.study_file);
        const std::string res = std::to_string(r.width) + "x" + std::to_string(r.height);
        Reference ref;
        // Named by the scene's content, not only its name: an edited scene file gets a new
        // reference instead of silently reusing the old one.
        ref.path = data / "references" /
                   (safe_name(fs::path(r.scene).stem().string()) + "-" +
                    scene_hash(self_contained_scene_json(scene)).substr(0, 12) + "-" + res +
                    "-" + std::to_string(reference_spp) + "spp.exr");
        if (!fs::exists(ref.path)) {
            std::fprintf(stderr, "study: reference %s %s at %llu spp\n", r.scene.c_str(),
                         res.c_str(), (unsigned long long)reference_spp);
            run_self({"reference", "--scene", scene, "--resolution", res, "--spp",
                      std::to_string(reference_spp), "--threads", std::to_string(threads),
                      "--out", ref.path.string()},
                     "reference for " + r.scene + " " + res);
        }
        ref.image = read_exr(ref.path);
        references[key] = std::move(ref);
    }

    std::unique_ptr<Backend> backend;
    // The embedded coordinator opens (and migrates) the database first; the study's own
    // connection shares it (SQLite WAL).
    if (opt.coordinator.empty())
        backend = std::make_unique<EmbeddedBackend>(data, threads);
    RunStore store(data);
    if (!opt.coordinator.empty())
        backend = std::make_unique<FarmBackend>(opt.coordinator, store, data);

    const int64_t now = unix_millis_now();
    store.put_study(
        {id, def.name,
         json{
             {"definition", def.source},
             {"scale",
              {{"name", scale.name},
               {"max_side", scale.max_side},
               {"spp_factor", scale.spp_factor},
               {"reference_spp", reference_spp},
               {"metric_bucket", renders.empty() ? 16u : renders.front().metric_bucket}}},
             // As given (studies/x.json), so the report can say how to re-run it.
             {"study_file", opt.study_file.is_absolute()
                                ? opt.study_file.filename().string()
                                : opt.study_file.lexically_normal().string()}}
             .dump(),
         now});

    std::map<std::string, StudyResult> results;
    for (StudyResult& r : store.study_results(id)) results[r.render_key] = std::move(r);

    std::map<std::string, size_t> index_of;
    for (size_t i = 0; i < renders.size(); ++i) index_of[renders[i].key] = i;
    std::map<std::string, std::string> in_flight;  // key -> id where it runs
    std::set<std::string> finished;                // keys done, in this run or before
    StudyRunSummary summary;
    summary.renders = renders.size();

    const auto spec_of = [&](const StudyRender& r) {
        RenderSpec spec;
        spec.scene_name = resolve_scene(r.scene, opt.study_file);
        spec.scene_json = self_contained_scene_json(spec.scene_name);
        spec.scene_name = r.scene;
        spec.width = r.width;
        spec.height = r.height;
        spec.seed = r.seed;
        spec.strategy = r.strategy;
        return spec;
    };
    const auto done_row = [&](const std::string& key) -> const StudyResult* {
        const auto it = results.find(key);
        if (it == results.end() || it->second.state != "done" || !finished.count(key))
            return nullptr;
        return &it->second;
    };
    const auto record = [&](StudyResult row) {
        row.study_id = id;
        row.updated_at = unix_millis_now();
        store.put_study_result(row);
        results[row.render_key] = std::move(row);
    };

    ProgressBar bar("study " + id);
    const auto draw = [&](const std::string& note) {
        uint64_t units = finished.size() * 1000;
        for (const auto& [key, remote] : in_flight) {
            const RenderStatus s = backend->status(remote);
            if (s.planned) units += std::min<uint64_t>(999, s.done * 1000 / s.planned);
        }
        bar.update(units, renders.size() * 1000, note);
    };

    // Pass 0 only adopts what an earlier run left in flight; then stale renders of the
    // embedded coordinator (resumed but no longer wanted) are cancelled.
    for (int pass = 0;; ++pass) {
        bool all_done = true;
        for (StudyRender& r : renders) {
            if (finished.count(r.key)) continue;
            all_done = false;
            if (in_flight.count(r.key)) continue;
            if (r.budget_from) {
                const StudyResult* src = done_row(r.source_key);
                const StudyResult* rate =
                    r.rate_key.empty() ? nullptr : done_row(r.rate_key);
                if (!src || (!r.rate_key.empty() && !rate)) continue;
                resolve_budget(r, uint64_t(src->samples), src->seconds,
                               rate ? rate->samples_per_second : 0.0);
            }
            const std::string spec = render_spec_json(r);
            const auto it = results.find(r.key);
            if (it != results.end() && it->second.spec_json == spec) {
                const StudyResult& row = it->second;
                if (row.state == "done") {
                    finished.insert(r.key);
                    continue;
                }
                if (row.origin == backend->origin()) {
                    const RenderStatus s = backend->status(row.remote_id);
                    if (s.known && s.state != "failed" && s.state != "cancelled") {
                        in_flight[r.key] = row.remote_id;
                        continue;
                    }
                }
            }
            if (pass == 0) continue;
            // The same spec under another key (a point two sweeps share, or a key an edit
            // of the file renamed): share it.
            bool shared = false, wait_for_twin = false;
            for (const auto& [key, row] : results) {
                if (key == r.key || row.spec_json != spec) continue;
                if (row.state == "done") {  // a finished render of exactly this spec
                    StudyResult copy = row;
                    copy.render_key = r.key;
                    record(copy);
                    finished.insert(r.key);
                    ++summary.reused;
                    shared = true;
                    break;
                }
                if (in_flight.count(key)) wait_for_twin = true;
            }
            if (shared || wait_for_twin) continue;
            if (!backend->parallel() && !in_flight.empty()) continue;
            const RenderSpec rs = spec_of(r);
            RenderSpec with_ref = rs;
            const Reference& ref = references.at(reference_key(r));
            with_ref.reference = ref.image;
            const std::string remote = backend->submit(with_ref, ref.path);
            in_flight[r.key] = remote;
            StudyResult row;
            row.render_key = r.key;
            row.spec_json = spec;
            row.origin = backend->origin();
            row.remote_id = remote;
            row.state = "submitted";
            record(row);
        }
        if (all_done) break;
        if (pass == 0) {
            std::set<std::string> wanted;
            for (const auto& [key, remote] : in_flight) wanted.insert(remote);
            for (const std::string& stale : backend->unfinished())
                if (!wanted.count(stale)) backend->cancel(stale);
            continue;
        }

        // Follow what runs; collect what finished.
        std::string note;
        for (auto it = in_flight.begin(); it != in_flight.end();) {
            const std::string key = it->first, remote = it->second;
            const RenderStatus s = backend->status(remote);
            if (!s.known || s.state == "failed" || s.state == "cancelled")
                throw CommandError(
                    "render " + key + " (" + remote + ") " +
                    (s.known ? s.state + (s.error.empty() ? "" : ": " + s.error)
                             : "vanished") +
                    "; run the study again to retry it");
            if (s.state != "done") {
                note = key + ", " + renders[index_of.at(key)].strategy.method;
                ++it;
                continue;
            }
            const StudyRender& r = renders[index_of.at(key)];
            const Collected c = backend->collect(remote, spec_of(r));
            const Reference& ref = references.at(reference_key(r));
            const ErrorMetrics m =
                compare_images(c.image, ref.image, int(r.metric_bucket));
            if (r.save_maps)
                write_maps(data / "maps" / (safe_name(key) + ".npy"), c.image, ref.image);
            StudyResult row = results.at(key);
            row.render_id = c.local_id;
            row.state = "done";
            row.samples = int64_t(c.samples);
            row.rays = int64_t(c.rays);
            row.seconds = c.seconds;
            row.samples_per_second = c.seconds > 0 ? double(c.samples) / c.seconds : 0;
            row.mean_abs = m.mean_abs;
            row.rmse = m.rmse;
            row.relative_mse = m.relative_mse;
            row.max_bucket = m.max_bucket;
            row.p99_bucket = m.p99_bucket;
            row.outcome_json = c.outcome_json;
            store.link_study_render(id, c.local_id);
            record(row);
            if (!isatty(STDERR_FILENO))  // no bar to watch: one line per render instead
                std::fprintf(stderr,
                             "study: %zu/%zu %s %s: %llu samples, %.2f s, E %.6g\n",
                             finished.size() + 1, renders.size(), key.c_str(),
                             r.strategy.method.c_str(), (unsigned long long)c.samples,
                             c.seconds, m.mean_abs);
            finished.insert(key);
            ++summary.rendered;
            it = in_flight.erase(it);
        }
        draw(in_flight.empty() ? ""
                               : std::to_string(finished.size() + 1) + "/" +
                                     std::to_string(renders.size()) + " " + note);
        if (!in_flight.empty()) backend->wait();
    }
    // Keys the file no longer has (edited since an earlier run) leave the study's
    // results; their renders stay in the database.
    for (const auto& [key, row] : results)
        if (!index_of.count(key)) store.remove_study_result(id, key);
    bar.update(renders.size() * 1000, renders.size() * 1000, "");
    bar.finish();
    backend.reset();
    summary.seconds = std::chrono::duration<double>(Clock::now() - started).count();
    return summary;
}

}  // namespace aliquot::cli
