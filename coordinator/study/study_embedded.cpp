#include "study_embedded.h"

#include <algorithm>
#include <chrono>
#include <thread>

#include "coordinator.h"
#include "worker_loop.h"

namespace aliquot {

namespace {

class EmbeddedBackend final : public StudyBackend {
public:
    EmbeddedBackend(const std::filesystem::path& data_dir, int threads)
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
    std::string submit(const RenderSpec& spec, const std::filesystem::path&) override {
        return coordinator_.submit(spec);
    }
    StudyRenderStatus status(const std::string& id) override {
        StudyRenderStatus s;
        if (const auto info = coordinator_.info(id)) {
            s.known = true;
            s.state = info->state;
            s.error = info->error;
            s.done = info->samples_done;
            s.planned = info->samples_planned;
        }
        return s;
    }
    CollectedRender collect(const std::string& id, const RenderSpec&,
                            RunStore&) override {
        const RenderInfo info = *coordinator_.info(id);
        CollectedRender c;
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
    static CoordinatorOptions options(const std::filesystem::path& data_dir) {
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

}  // namespace

std::unique_ptr<StudyBackend> make_embedded_backend(const std::filesystem::path& data_dir,
                                                    int threads) {
    return std::make_unique<EmbeddedBackend>(data_dir, threads);
}

}  // namespace aliquot
