#include "trace_job.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <exception>
#include <stdexcept>
#include <thread>
#include <vector>

#include "camera_model.h"
#include "camera_rays.h"
#include "cell_batches.h"

namespace aliquot {

namespace {

// One thread's tracing of cells: their batches (cell_batches.h), each pixel's samples
// added to its sums in index order, as its batches come in order.
class CellTracer {
public:
    CellTracer(const PathTracer& tracer, const CameraModel& camera,
               const RenderGeometry& geometry, const SampleJob& job,
               SampleJobResult& result, const std::atomic<bool>* cancel)
        : tracer_(tracer),
          camera_(camera),
          geometry_(geometry),
          job_(job),
          result_(result),
          cancel_(cancel) {}

    void trace(const PixelRect& cell) {
        for_each_batch(job_, cell, batch_,
                       [this](const SampleBatch& b) { trace_batch(b); });
    }

private:
    void trace_batch(const SampleBatch& b) {
        // Also between a cell's batches: a cell of a steered round may hold many.
        if (cancel_ && cancel_->load()) throw JobCancelled();
        for (int j = 0; j < b.count; j += PathLanes::kMax)
            camera_rays(camera_, geometry_.seed, &b.x[j], &b.y[j], &b.k[j],
                        std::min(PathLanes::kMax, b.count - j), &dirs_[j], &rngs_[j]);
        tracer_.radiance_batch(camera_.origin(), dirs_.data(), b.count, rngs_.data(),
                               radiance_.data(), job_.aux ? first_hits_.data() : nullptr);
        for (int j = 0; j < b.count; ++j)
            add_sample(result_.pixels[b.pixel[j]], b.k[j], radiance_[j].value,
                       radiance_[j].rays);
        if (job_.aux)
            for (int j = 0; j < b.count; ++j)
                add_first_hit(result_.first_hits[b.pixel[j]], first_hits_[j].albedo,
                              first_hits_[j].normal);
    }

    const PathTracer& tracer_;
    const CameraModel& camera_;
    const RenderGeometry& geometry_;
    const SampleJob& job_;
    SampleJobResult& result_;
    const std::atomic<bool>* cancel_;
    SampleBatch batch_;
    std::array<Vec3, SampleBatch::kMax> dirs_;
    std::vector<SampleRng> rngs_ = std::vector<SampleRng>(
        SampleBatch::kMax, SampleRng::at(0, 1));  // camera_rays seeds them
    std::array<Radiance, SampleBatch::kMax> radiance_;
    std::array<FirstHit, SampleBatch::kMax> first_hits_;  // with job_.aux only
};

}  // namespace

SampleJobResult trace_sample_job(const PathTracer& tracer, const RenderGeometry& geometry,
                                 const SampleJob& job, int threads,
                                 const std::atomic<bool>* cancel) {
    const auto start = std::chrono::steady_clock::now();
    const PixelRect& r = job.rect;
    if (job.counts.size() != r.size() || job.first_sample.size() != r.size())
        throw std::invalid_argument(
            "sample job: per-pixel arrays do not match its rectangle");
    if (r.x > geometry.width || r.width > geometry.width - r.x || r.y > geometry.height ||
        r.height > geometry.height - r.y)
        throw std::invalid_argument("sample job: rectangle lies outside the image");

    SampleJobResult result;
    result.rect = r;
    result.pixels.resize(r.size());
    if (job.aux) result.first_hits.resize(r.size());
    const CameraModel camera(tracer.scene().camera, geometry.width, geometry.height);

    // Threads take whole cells, so each batch is traced by one thread as one batch.
    const JobCells cells(r);
    std::atomic<size_t> next_cell{0};
    std::atomic<bool> failed{false};
    auto work = [&] {
        enable_flush_to_zero();
        CellTracer cell_tracer(tracer, camera, geometry, job, result, cancel);
        for (size_t c; (c = next_cell.fetch_add(1)) < cells.count();) {
            if ((cancel && cancel->load()) || failed.load()) return;
            cell_tracer.trace(cells[c]);
        }
    };
    // No exception may leave a thread: the first one is thrown here once all have joined.
    const size_t extra = std::min<size_t>(size_t(std::max(threads, 1)),
                                          std::max<size_t>(cells.count(), 1)) -
                         1;
    std::vector<std::exception_ptr> errors(extra);
    std::vector<std::jthread> pool;
    for (size_t t = 0; t < extra; ++t)
        pool.emplace_back([&, t] {
            try {
                work();
            } catch (...) {
                errors[t] = std::current_exception();
                failed = true;
            }
        });
    std::exception_ptr own;
    try {
        work();
    } catch (...) {
        own = std::current_exception();
        failed = true;
    }
    pool.clear();  // joins
    if (own) std::rethrow_exception(own);
    for (const std::exception_ptr& e : errors)
        if (e) std::rethrow_exception(e);
    if (cancel && cancel->load()) throw JobCancelled();

    result.wall_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

}  // namespace aliquot
