// Do rays track time? optimal-time spends samples by rays per sample because rays are
// deterministic; that is only sound if a job's wall time is proportional to its rays.
// Traces every 16x16 tile of a scene on one thread and prints, as JSON, the correlation
// of per-tile rays with per-tile seconds and the spread of seconds per ray across tiles.
#include <cmath>
#include <cstdio>
#include <vector>

#include "scene_loader.h"
#include "trace_job.h"

using namespace aliquot;

int main(int argc, char** argv) {
    const std::string name = argc > 1 ? argv[1] : "cornell-caustics";
    const uint32_t side = 128, tile = 16,
                   spp = argc > 2 ? uint32_t(std::atoi(argv[2])) : 32;
    const Scene scene = load_scene(name);
    const PathTracer tracer(scene);
    enable_flush_to_zero();
    std::vector<double> rays, seconds;
    for (uint32_t y = 0; y < side; y += tile)
        for (uint32_t x = 0; x < side; x += tile) {
            SampleJob job;
            job.rect = {x, y, tile, tile};
            job.counts.assign(job.rect.size(), spp);
            job.first_sample.assign(job.rect.size(), 0);
            const SampleJobResult r = trace_sample_job(tracer, {side, side, 1}, job);
            rays.push_back(double(r.total_rays()));
            seconds.push_back(r.wall_seconds);
        }
    const double n = double(rays.size());
    double mr = 0, ms = 0;
    for (size_t i = 0; i < rays.size(); ++i) mr += rays[i] / n, ms += seconds[i] / n;
    double srr = 0, sss = 0, srs = 0, mean_spr = 0, sq_spr = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        srr += (rays[i] - mr) * (rays[i] - mr);
        sss += (seconds[i] - ms) * (seconds[i] - ms);
        srs += (rays[i] - mr) * (seconds[i] - ms);
        const double spr = seconds[i] / rays[i];
        mean_spr += spr / n;
        sq_spr += spr * spr / n;
    }
    double rmin = rays[0], rmax = rays[0];
    for (double r : rays) rmin = std::min(rmin, r), rmax = std::max(rmax, r);
    std::printf(
        "{\"scene\": \"%s\", \"tiles\": %zu, \"spp\": %u, \"rays_max_over_min\": %.3f, "
        "\"correlation_rays_seconds\": %.4f, \"seconds_per_ray_cv\": %.4f}\n",
        name.c_str(), rays.size(), spp, rmax / rmin, srs / std::sqrt(srr * sss),
        std::sqrt(std::max(0.0, sq_spr - mean_spr * mean_spr)) / mean_spr);
}
