#include "study_farm.h"

#include <chrono>
#include <fstream>
#include <sstream>
#include <thread>

#include "client.h"
#include "exr_io.h"
#include "render_proto.h"
#include "store.h"

namespace aliquot::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Mirrors a farm render and its rounds into the study's database, so one database holds
// the whole study whichever way it ran.
void mirror_render(RunStore& store, const CollectedRender& c, const RenderSpec& spec,
                   const v1::RenderInfo& info, const v1::GetRoundsReply& rounds,
                   const std::string& origin) {
    const int64_t now = unix_millis_now();
    const std::string hash = scene_hash(spec.scene_json);
    store.put_scene(hash, spec.scene_name, spec.scene_json, now);
    if (!store.get_render(c.local_id)) {
        RenderRecord rec;
        rec.id = c.local_id;
        rec.scene_hash = hash;
        rec.spec_json = json{{"scene_name", spec.scene_name}, {"width", spec.width},
                             {"height", spec.height},         {"seed", spec.seed},
                             {"strategy", spec.strategy},     {"farm", origin},
                             {"farm_id", info.id()}}
                            .dump();
        rec.created_at = info.created_ms() ? info.created_ms() : now;
        rec.samples_planned = int64_t(info.samples_planned());
        rec.samples_done = int64_t(info.samples_done());
        store.create_render(rec);
    }
    for (const v1::RoundInfo& r : rounds.rounds()) {
        RoundRecord rec;
        rec.render_id = c.local_id;
        rec.idx = r.index();
        rec.samples_in_round = int64_t(r.samples_in_round());
        rec.samples_total = int64_t(r.samples_total());
        rec.seconds = r.seconds();
        rec.error_estimate = r.error_estimate();
        if (r.error_vs_reference() >= 0) rec.error_vs_reference = r.error_vs_reference();
        rec.created_at = now;
        store.add_round(rec);
    }
    store.finish_render(c.local_id, RenderState::Done, c.outcome_json, now);
}

class FarmBackend final : public StudyBackend {
public:
    FarmBackend(const CoordinatorEndpoint& endpoint, const fs::path& data_dir)
        : connection_(endpoint), data_dir_(data_dir) {}

    std::string origin() const override { return "farm " + connection_.address(); }
    bool parallel() const override { return true; }
    std::string submit(const RenderSpec& spec, const fs::path& reference_path) override {
        v1::SubmitRequest req;
        req.set_scene(spec.scene_name);
        req.set_scene_json(spec.scene_json);
        req.set_width(spec.width);
        req.set_height(spec.height);
        req.set_seed(spec.seed);
        req.set_strategy_json(json(spec.strategy).dump());
        req.set_albedo_normal(spec.aux);  // a study that denoises
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
    StudyRenderStatus status(const std::string& id) override {
        v1::GetRenderRequest req;
        req.set_id(id);
        v1::RenderInfo info;
        const grpc::Status st =
            connection_.stub().GetRender(connection_.context().get(), req, &info);
        StudyRenderStatus s;
        if (st.error_code() == grpc::StatusCode::NOT_FOUND) return s;
        connection_.check(st, "status " + id);
        s.known = true;
        s.state = from_proto(info.state());
        s.error = info.error();
        s.done = info.samples_done();
        s.planned = info.samples_planned();
        return s;
    }
    CollectedRender collect(const std::string& id, const RenderSpec& spec,
                            RunStore& store) override {
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
        CollectedRender c;
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
        mirror_render(store, c, spec, info, rounds, origin());
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
    fs::path data_dir_;
};

}  // namespace

std::unique_ptr<StudyBackend> make_farm_backend(const CoordinatorEndpoint& endpoint,
                                                const fs::path& data_dir) {
    return std::make_unique<FarmBackend>(endpoint, data_dir);
}

}  // namespace aliquot::cli
