#include "trace_job.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <optional>
#include <stdexcept>
#include <thread>
#include <vector>

#include "camera_model.h"
#include "camera_rays.h"

namespace aliquot {

namespace {

void trace_row(const PathTracer& tracer, const CameraModel& camera,
               const RenderGeometry& geometry, const SampleJob& job, uint32_t row,
               SampleJobResult& result) {
    constexpr int kBatch = PathTracer::kBatch;
    const PixelRect& r = job.rect;
    std::vector<SampleRng> rngs(kBatch, SampleRng::at(0, 1));  // camera_rays seeds them
    std::array<Vec3, kBatch> dirs;
    std::array<Radiance, kBatch> radiance;
    for (uint32_t col = 0; col < r.width; ++col) {
        const size_t i = size_t(row) * r.width + col;
        const uint32_t x = r.x + col, y = r.y + row;
        PixelSums& sums = result.pixels[i];
        const uint64_t first = job.first_sample[i], end = first + job.counts[i];
        // The pixel's samples are traced together, kBatch at a time, cut from its first
        // sample here. A job holds all of a pixel's samples of its round, so which
        // samples share a batch (and so Embree's packets) follows from the render's
        // rounds, never from how rounds are cut into jobs or jobs spread over threads and
        // workers.
        for (uint64_t k0 = first; k0 < end; k0 += kBatch) {
            const int n = int(std::min<uint64_t>(kBatch, end - k0));
            camera_rays(camera, geometry.seed, x, y, k0, n, dirs.data(), rngs.data());
            tracer.radiance_batch(camera.origin(), dirs.data(), n, rngs.data(),
                                  radiance.data());
            for (int j = 0; j < n; ++j)
                add_sample(sums, k0 + j, radiance[j].value, radiance[j].rays);
        }
    }
}

}  // namespace

SampleJobResult trace_sample_job(const PathTracer& tracer, const RenderGeometry& geometry,
                                 const SampleJob& job, int threads,
                                 const std::atomic<bool>* cancel) {
    const auto start = std::chrono::steady_clock::now();
    const PixelRect& r = job.rect;
    if (job.counts.size() != r.size() || job.first_sample.size() != r.size())
        throw std::invalid_argument(
            "sample job: per-pixel arrays do not match its rectangle");
    if (r.x + r.width > geometry.width || r.y + r.height > geometry.height)
        throw std::invalid_argument("sample job: rectangle lies outside the image");

    SampleJobResult result;
    result.rect = r;
    result.pixels.resize(r.size());
    const CameraModel camera(tracer.scene().camera, geometry.width, geometry.height);

    std::atomic<uint32_t> next_row{0};
    auto work = [&] {
        enable_flush_to_zero();
        for (uint32_t row; (row = next_row.fetch_add(1)) < r.height;) {
            if (cancel && cancel->load()) return;
            trace_row(tracer, camera, geometry, job, row, result);
        }
    };
    const int extra = std::max(0, std::min<int>(threads, int(r.height)) - 1);
    std::vector<std::jthread> pool;
    for (int t = 0; t < extra; ++t) pool.emplace_back(work);
    work();
    pool.clear();  // joins
    if (cancel && cancel->load()) throw JobCancelled();

    result.wall_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

}  // namespace aliquot
