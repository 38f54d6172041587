#include "study_runner.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <set>
#include <thread>

#include "error_metric.h"
#include "scene_loader.h"
#include "study_denoise.h"
#include "study_embedded.h"
#include "study_maps.h"
#include "study_plan.h"
#include "study_recorder.h"
#include "study_references.h"

namespace aliquot {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// The loop over a study's renders: adopt what earlier runs recorded or left running,
// share results between keys of equal spec, submit what is runnable, collect what is
// done.
class StudyRun {
public:
    StudyRun(std::vector<StudyRender>& renders, StudyBackend& backend,
             StudyRecorder& recorder, const StudyReferences& references,
             const StudyRunOptions& options)
        : renders_(renders),
          backend_(backend),
          recorder_(recorder),
          references_(references),
          options_(options) {
        for (size_t i = 0; i < renders_.size(); ++i) index_of_[renders_[i].key] = i;
    }

    // Pass 0 only adopts what an earlier run left in flight; then stale renders of the
    // embedded coordinator (resumed but no longer wanted) are cancelled.
    StudyRunSummary run() {
        summary_.renders = renders_.size();
        for (int pass = 0;; ++pass) {
            bool all_done = true;
            for (StudyRender& r : renders_)
                if (!finished_.count(r.key)) {
                    all_done = false;
                    step(r, pass);
                }
            if (all_done) break;
            if (pass == 0) {
                cancel_stale();
                continue;
            }
            const std::string note = follow();
            draw(in_flight_.empty() ? ""
                                    : std::to_string(finished_.size() + 1) + "/" +
                                          std::to_string(renders_.size()) + " " + note);
            if (!in_flight_.empty()) backend_.wait();
        }
        recorder_.forget_unless(index_of_);
        const uint64_t total = renders_.size() * 1000;
        if (options_.progress) options_.progress(total, total, "");
        if (options_.done) options_.done();
        return summary_;
    }

private:
    void step(StudyRender& r, int pass) {
        if (in_flight_.count(r.key)) return;
        if (r.budget_from && !resolve(r)) return;
        const std::string spec = render_spec_json(r);
        if (adopt(r, spec) || pass == 0 || share(r, spec)) return;
        if (!backend_.parallel() && !in_flight_.empty()) return;
        submit(r, spec);
    }

    // A dependent render's budget, once the renders it depends on are done.
    bool resolve(StudyRender& r) const {
        const StudyResult* src = done_row(r.source_key);
        const StudyResult* rate = r.rate_key.empty() ? nullptr : done_row(r.rate_key);
        if (!src || (!r.rate_key.empty() && !rate)) return false;
        resolve_budget(r, uint64_t(src->samples), src->seconds,
                       rate ? rate->samples_per_second : 0.0);
        return true;
    }

    const StudyResult* done_row(const std::string& key) const {
        const StudyResult* row = recorder_.find(key);
        return row && row->state == "done" && finished_.count(key) ? row : nullptr;
    }

    // Recorded before with this spec: done, or still running on this backend.
    bool adopt(const StudyRender& r, const std::string& spec) {
        const StudyResult* row = recorder_.find(r.key);
        if (!row || row->spec_json != spec) return false;
        if (row->state == "done") {
            finished_.insert(r.key);
            return true;
        }
        if (row->origin != backend_.origin()) return false;
        const StudyRenderStatus s = backend_.status(row->remote_id);
        if (!s.known || s.state == RenderState::Failed ||
            s.state == RenderState::Cancelled)
            return false;
        in_flight_[r.key] = row->remote_id;
        return true;
    }

    // The same spec under another key (a point two sweeps share, or a key an edit of the
    // file renamed): take its result, or wait while it runs.
    bool share(const StudyRender& r, const std::string& spec) {
        bool wait_for_twin = false;
        for (const auto& [key, row] : recorder_.results()) {
            if (key == r.key || row.spec_json != spec) continue;
            if (row.state == "done") {
                StudyResult copy = row;
                copy.render_key = r.key;
                recorder_.record(copy);
                finished_.insert(r.key);
                ++summary_.reused;
                return true;
            }
            if (in_flight_.count(key)) wait_for_twin = true;
        }
        return wait_for_twin;
    }

    RenderSpec spec_of(const StudyRender& r) const {
        RenderSpec spec;
        spec.scene_json =
            self_contained_scene_json(resolve_scene(r.scene, options_.study_file));
        spec.scene_name = r.scene;
        spec.width = r.width;
        spec.height = r.height;
        spec.seed = r.seed;
        spec.strategy = r.strategy;
        spec.aux = r.denoise;
        if (r.strategy.method == "oracle")
            spec.strategy.true_sigma = references_.at(reference_key(r)).sigma;
        return spec;
    }

    void submit(const StudyRender& r, const std::string& spec) {
        RenderSpec with_ref = spec_of(r);
        const StudyReference& ref = references_.at(reference_key(r));
        with_ref.reference = ref.image;
        const std::string remote = backend_.submit(with_ref, ref.path);
        in_flight_[r.key] = remote;
        recorder_.record_submitted(r.key, spec, backend_.origin(), remote);
    }

    void cancel_stale() {
        std::set<std::string> wanted;
        for (const auto& [key, remote] : in_flight_) wanted.insert(remote);
        for (const std::string& stale : backend_.unfinished())
            if (!wanted.count(stale)) backend_.cancel(stale);
    }

    // Follows what runs and collects what finished; the note names one that still runs.
    std::string follow() {
        std::string note;
        for (auto it = in_flight_.begin(); it != in_flight_.end();) {
            const std::string key = it->first, remote = it->second;
            const StudyRenderStatus s = backend_.status(remote);
            if (!s.known || s.state == RenderState::Failed ||
                s.state == RenderState::Cancelled)
                throw StudyError("render " + key + " (" + remote + ") " +
                                 (s.known ? std::string(to_string(s.state)) +
                                                (s.error.empty() ? "" : ": " + s.error)
                                          : "vanished") +
                                 "; run the study again to retry it");
            if (s.state != RenderState::Done) {
                note = key + ", " + renders_[index_of_.at(key)].strategy.method;
                ++it;
                continue;
            }
            collect(key, remote);
            it = in_flight_.erase(it);
        }
        return note;
    }

    void collect(const std::string& key, const std::string& remote) {
        const StudyRender& r = renders_[index_of_.at(key)];
        const CollectedRender c = backend_.collect(remote, spec_of(r), recorder_.store());
        const StudyReference& ref = references_.at(reference_key(r));
        const ErrorMetrics m = compare_images(c.image, ref.image, int(r.metric_bucket));
        std::optional<ErrorMetrics> denoised;
        if (r.denoise)
            denoised = compare_images(denoise_render(denoiser(), c.image, key), ref.image,
                                      int(r.metric_bucket));
        if (r.save_maps)
            write_study_maps(
                options_.out / "data" / "maps" / (safe_file_name(key) + ".npy"), c.image,
                ref.image);
        recorder_.record_done(key, c, m, denoised);
        if (!isatty(STDERR_FILENO))  // no bar to watch: one line per render instead
            std::fprintf(
                stderr,
                "study: %zu/%zu %s %s: %llu samples, %.2f s, E %.6g, mean bias %s%s\n",
                finished_.size() + 1, renders_.size(), key.c_str(),
                r.strategy.method.c_str(), (unsigned long long)c.samples, c.seconds,
                m.mean_abs, mean_bias_text(m).c_str(),
                denoised ? (", denoised " + std::to_string(denoised->mean_abs)).c_str()
                         : "");
        finished_.insert(key);
        ++summary_.rendered;
    }

    // Open Image Denoise, opened by the first render measured after denoising.
    const Denoiser& denoiser() {
        if (!denoiser_) {
            std::string error;
            denoiser_ = Denoiser::open(&error);
            if (!denoiser_) throw StudyError("the study denoises: " + error);
        }
        return *denoiser_;
    }

    void draw(const std::string& note) {
        if (!options_.progress) return;
        uint64_t units = finished_.size() * 1000;
        for (const auto& [key, remote] : in_flight_) {
            const StudyRenderStatus s = backend_.status(remote);
            if (s.planned) units += std::min<uint64_t>(999, s.done * 1000 / s.planned);
        }
        options_.progress(units, renders_.size() * 1000, note);
    }

    std::vector<StudyRender>& renders_;
    StudyBackend& backend_;
    StudyRecorder& recorder_;
    const StudyReferences& references_;
    const StudyRunOptions& options_;
    std::map<std::string, size_t> index_of_;
    std::map<std::string, std::string> in_flight_;  // key -> id where it runs
    std::set<std::string> finished_;                // keys done, in this run or before
    StudyRunSummary summary_;
    std::unique_ptr<Denoiser> denoiser_;
};

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
    const StudyReferences references = prepare_references(
        renders, opt.study_file, data / "references", reference_spp, threads);

    // The backend opens (and migrates) the database first; the study's own connection
    // shares it (SQLite WAL).
    std::unique_ptr<StudyBackend> backend =
        opt.backend ? opt.backend(data) : make_embedded_backend(data, threads);
    RunStore store(data);
    StudyRecorder recorder(store, id);
    recorder.record_study(def, scale, reference_spp,
                          renders.empty() ? 16u : renders.front().metric_bucket,
                          opt.study_file);
    StudyRunSummary summary =
        StudyRun(renders, *backend, recorder, references, opt).run();
    backend.reset();
    summary.seconds = std::chrono::duration<double>(Clock::now() - started).count();
    return summary;
}

}  // namespace aliquot
