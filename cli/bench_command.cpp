// aliquot bench: our path tracer's throughput as a ratio to raw Embree on the same scene,
// both measured in this one run so the machine cancels out.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <numbers>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "embedded_render.h"
#include "incoherent_rays.h"
#include "path_tracer.h"
#include "render_options.h"
#include "scene_loader.h"

namespace aliquot::cli {

namespace {

// rtcIntersect1 on incoherent rays (incoherent_rays.h), 4 passes with `threads` threads.
double raw_embree_rays_per_second(const PathTracer& tracer, const Scene& scene,
                                  int threads) {
    // Rays are made before the clock starts: only rtcIntersect1 is timed.
    constexpr size_t kRays = size_t(1) << 21;
    const std::vector<RawRay> rays = incoherent_rays(scene, kRays);
    constexpr int kPasses = 4;
    std::atomic<size_t> next{0};
    std::atomic<uint64_t> hits{0};
    auto work = [&] {
        enable_flush_to_zero();
        uint64_t local_hits = 0;
        constexpr size_t kChunk = 4096;
        for (size_t begin; (begin = next.fetch_add(kChunk)) < kRays * kPasses;) {
            for (size_t i = begin; i < std::min(begin + kChunk, kRays * kPasses); ++i) {
                Hit hit;
                const RawRay& ray = rays[i % kRays];
                local_hits += tracer.embree().intersect(ray.origin, ray.dir, 1e30f, hit);
            }
        }
        hits += local_hits;
    };
    const auto start = std::chrono::steady_clock::now();
    {
        std::vector<std::jthread> pool;
        for (int t = 0; t < threads; ++t) pool.emplace_back(work);
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return double(kRays) * kPasses / seconds;
}

struct BenchCommand {
    RenderOptions options;
    bool json = false;

    void run() {
        check_render_options(options);
        check_fits_in_memory(options);
        const Scene scene = load_scene(options.scene);
        const PathTracer tracer(scene);
        const double raw = raw_embree_rays_per_second(tracer, scene, options.threads);

        const RenderSpec spec = make_render_spec(options);
        const RenderInfo info = render_embedded(spec, options.threads, false).info;
        const double sps = double(info.samples_done) / info.seconds;
        const double rps = double(info.rays) / info.seconds;
        nlohmann::json out = {
            {"scene", options.scene},
            {"width", options.width},
            {"height", options.height},
            {"spp", options.spp},
            {"threads", options.threads},
            {"samples_per_second", sps},
            {"rays_per_second", rps},
            {"rays_per_sample", double(info.rays) / double(info.samples_done)},
            {"embree_raw_rays_per_second", raw},
            {"ray_utilization", rps / raw}};
        if (json)
            std::cout << out.dump() << std::endl;
        else
            std::cout << out.dump(2) << std::endl;
    }
};

}  // namespace

void register_bench(CLI::App& app) {
    auto command = std::make_shared<BenchCommand>();
    CLI::App* cmd = app.add_subcommand(
        "bench",
        "path tracer samples/s and rays/s against raw Embree rays/s, in one run");
    add_render_options(*cmd, command->options);
    cmd->add_flag("--json", command->json, "print one JSON object on one line");
    cmd->callback([command] { command->run(); });
}

}  // namespace aliquot::cli
