// The coordinator's merge throughput: results for a whole render handed to
// Coordinator::complete as fast as one thread can, without tracing (results are synthetic
// but valid). Prints pixel-samples merged per second and jobs per second, as JSON.
#include <chrono>
#include <cstdio>

#include "coordinator.h"
#include "scene_loader.h"
#include "synthetic_result.h"

using namespace aliquot;

int main(int argc, char** argv) {
    const uint32_t side = argc > 1 ? uint32_t(std::atoi(argv[1])) : 1024;
    const uint32_t spp = argc > 2 ? uint32_t(std::atoi(argv[2])) : 64;
    Coordinator coordinator(CoordinatorOptions{});
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = spec.height = side;
    spec.strategy.method = "uniform";
    spec.strategy.spp = spp;
    const std::string id = coordinator.submit(spec);

    uint64_t jobs = 0, pixel_samples = 0, pixels = 0;
    double seconds = 0;
    const std::string session = coordinator.register_worker("bench", 1).session;
    while (auto grant = coordinator.lease(session, std::chrono::milliseconds(0))) {
        const SampleJobResult r = bench::synthetic_result(*grant);
        const auto start = std::chrono::steady_clock::now();
        coordinator.complete(session, grant->lease_id, r);
        seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
                       .count();
        ++jobs;
        pixels += r.pixels.size();
        pixel_samples += r.total_samples();
    }
    std::printf(
        "{\"image\": \"%ux%u\", \"spp\": %u, \"jobs\": %llu, \"merge_seconds\": %.4f, "
        "\"pixels_merged_per_second\": %.0f, \"pixel_samples_merged_per_second\": %.0f, "
        "\"jobs_per_second\": %.0f, \"state\": \"%s\"}\n",
        side, side, spp, (unsigned long long)jobs, seconds, double(pixels) / seconds,
        double(pixel_samples) / seconds, double(jobs) / seconds,
        std::string(to_string(coordinator.info(id)->state)).c_str());
}
