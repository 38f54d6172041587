// How long the coordinator's lock makes workers wait at a round's end. One process: a
// Coordinator with a data directory (so checkpoints and the EXR are written), a real
// WorkerLoop tracing a one-round uniform render, and a probe thread that calls Lease (and
// gives back any job it gets) and ListWorkers back to back, timing each call.
// Prints the longest and the 99th-percentile wait per call while the render runs; the
// render's round end (checkpoint, then the EXR) is where the long waits were.
//
// Usage: lease_latency WxH [threads]   (e.g. lease_latency 2048x2048 1)
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "coordinator.h"
#include "scene_loader.h"
#include "worker_loop.h"

using namespace aliquot;
using Clock = std::chrono::steady_clock;

namespace {

double ms_since(Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

void report(const char* name, std::vector<double> v) {
    if (v.empty()) return;
    std::sort(v.begin(), v.end());
    std::printf("%-12s calls %7zu  median %8.3f ms  p99 %8.3f ms  max %8.1f ms\n", name,
                v.size(), v[v.size() / 2], v[std::min(v.size() - 1, v.size() * 99 / 100)],
                v.back());
}

}  // namespace

int main(int argc, char** argv) {
    uint32_t width = 2048, height = 2048;
    if (argc > 1 && std::sscanf(argv[1], "%ux%u", &width, &height) != 2) {
        std::fprintf(stderr, "usage: lease_latency WxH [threads]\n");
        return 2;
    }
    const int threads = argc > 2 ? std::atoi(argv[2]) : 1;
    const auto dir = std::filesystem::temp_directory_path() /
                     ("aliquot-lease-latency-" + std::to_string(getpid()));
    std::filesystem::remove_all(dir);

    CoordinatorOptions options;
    options.data_dir = dir;
    std::vector<double> lease_ms, workers_ms;
    {
        Coordinator coordinator(options);
        RenderSpec spec;
        spec.scene_name = "cornell-box";
        spec.scene_json = self_contained_scene_json("cornell-box");
        spec.width = width;
        spec.height = height;
        spec.strategy.method = "uniform";
        spec.strategy.spp = 1;
        const auto t0 = Clock::now();
        const std::string id = coordinator.submit(spec);

        WorkerLoop worker(coordinator, {"tracer", threads, std::chrono::milliseconds(500),
                                        /*quiet=*/true});
        std::thread pool([&] { worker.run(); });
        std::atomic<bool> done{false};
        const std::string probe_session = coordinator.register_worker("probe", 1).session;
        std::thread probe([&] {
            while (!done) {
                auto t = Clock::now();
                auto grant =
                    coordinator.lease(probe_session, std::chrono::milliseconds(0));
                lease_ms.push_back(ms_since(t));
                if (grant) coordinator.abandon(probe_session, grant->lease_id);
                t = Clock::now();
                coordinator.workers();
                workers_ms.push_back(ms_since(t));
                std::this_thread::sleep_for(std::chrono::milliseconds(2));
            }
        });
        // Finished once the render is done and its image is on disk.
        while (true) {
            const auto info = coordinator.info(id);
            if (info && is_terminal(info->state) &&
                std::filesystem::exists(dir / "renders" / id / "image.exr"))
                break;
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
        // A little longer: the end's write may still be running.
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
        done = true;
        probe.join();
        worker.stop();
        pool.join();
        std::printf("%ux%u, 1 spp, %d tracing thread(s): %.1f s\n", width, height,
                    threads, ms_since(t0) / 1000);
    }
    report("Lease", lease_ms);
    report("ListWorkers", workers_ms);
    std::filesystem::remove_all(dir);
    return 0;
}
