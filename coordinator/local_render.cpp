#include "local_render.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <thread>

#include "round_cutter.h"

namespace aliquot {

RenderStats render_locally(const PathTracer& tracer, const RenderGeometry& geometry,
                           Strategy& strategy, Accumulator& merged, int threads,
                           const ProgressFn& progress) {
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    RenderStats stats;
    const uint64_t samples_before = merged.total_samples();
    const uint64_t rays_before = merged.total_rays();
    const uint64_t nonfinite_before = merged.total_nonfinite();
    threads = std::max(threads, 1);

    while (auto round = strategy.next_round(merged)) {
        const std::vector<SampleJob> jobs = cut_round(*round, merged);
        std::atomic<size_t> next_job{0};
        std::mutex mutex;
        std::condition_variable ready;
        std::deque<SampleJobResult> done;
        std::exception_ptr failure;

        // Workers trace; this thread merges as results arrive. Jobs cover disjoint pixels,
        // so the merge order cannot change any pixel's sum.
        auto work = [&] {
            for (size_t j; (j = next_job.fetch_add(1)) < jobs.size();) {
                SampleJobResult r;
                try {
                    r = trace_sample_job(tracer, geometry, jobs[j], 1);
                } catch (...) {
                    std::lock_guard lock(mutex);
                    if (!failure) failure = std::current_exception();
                    next_job = jobs.size();
                    ready.notify_one();
                    return;
                }
                std::lock_guard lock(mutex);
                done.push_back(std::move(r));
                ready.notify_one();
            }
        };
        std::vector<std::jthread> pool;
        for (int t = 0; t < threads; ++t) pool.emplace_back(work);

        for (size_t merged_jobs = 0; merged_jobs < jobs.size();) {
            std::unique_lock lock(mutex);
            ready.wait(lock, [&] { return !done.empty() || failure; });
            if (failure) break;
            SampleJobResult r = std::move(done.front());
            done.pop_front();
            lock.unlock();
            merged.merge(r);
            ++merged_jobs;
            if (progress)
                progress({round->index, merged.total_samples(), strategy.planned_samples(),
                          elapsed()});
        }
        pool.clear();
        if (failure) std::rethrow_exception(failure);
        ++stats.rounds;
    }
    stats.seconds = elapsed();
    stats.samples = merged.total_samples() - samples_before;
    stats.rays = merged.total_rays() - rays_before;
    stats.nonfinite = merged.total_nonfinite() - nonfinite_before;
    return stats;
}

}  // namespace aliquot
