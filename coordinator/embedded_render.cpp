#include "embedded_render.h"

#include <thread>

#include "worker_loop.h"

namespace aliquot {

EmbeddedResult render_embedded(const RenderSpec& spec, int threads, bool aovs,
                               const std::function<void(const RenderInfo&)>& progress) {
    CoordinatorOptions options;
    // Local threads never vanish, but keep leases long so a slow job is never re-issued.
    options.lease_time = std::chrono::hours(24);
    options.worker_lost_after = std::chrono::hours(24);
    Coordinator coordinator(options);
    const std::string id = coordinator.submit(spec);

    WorkerLoop workers(coordinator, {"local", std::max(threads, 1),
                                     std::chrono::milliseconds(500), /*quiet=*/true});
    std::jthread pool([&] { workers.run(); });

    uint64_t seen = 0;
    RenderInfo info;
    while (true) {
        seen = coordinator.wait_for_change(seen, std::chrono::milliseconds(100));
        info = *coordinator.info(id);
        if (is_terminal(info.state)) break;
        if (progress) progress(info);
        // Every merged job is a change; reading the render's state on each would contend
        // for the coordinator's lock with the threads doing the work. A progress bar
        // needs less.
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    workers.stop();
    // Wakes the threads long-polling for a lease: without it the process waited out
    // the poll, 500 ms, after every render.
    coordinator.stop();
    pool.join();
    if (progress) progress(info);
    if (info.state == RenderState::Failed)
        throw std::runtime_error("render failed: " + info.error);
    EmbeddedResult result{info, *coordinator.image(id, aovs)};
    return result;
}

}  // namespace aliquot
