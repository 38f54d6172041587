// The coordinator's Prometheus metrics (docs/API.md, `GET /metrics`), served as /metrics
// by the HTTP server. The call latencies are observed by the gRPC services at the call
// boundary; everything else is read from the Coordinator when scraped, so it cannot drift
// from the farm. Labels take values from fixed sets only (render and worker states, a
// lease's outcome), never a render id or a worker name: a scrape stays the same size
// however long the farm runs.
#pragma once

#include <memory>
#include <string>

#include "coordinator.h"

namespace aliquot {

class FarmMetrics {
public:
    explicit FarmMetrics(Coordinator& coordinator);
    ~FarmMetrics();
    FarmMetrics(const FarmMetrics&) = delete;
    FarmMetrics& operator=(const FarmMetrics&) = delete;

    // How long a Lease took to answer, its long-poll wait included (up to 30 s), and
    // whether it handed out a job. Thread-safe, as are the others.
    void observe_lease(double seconds, bool granted);
    // How long merging one result took (Coordinator::complete): a round's end, when it
    // was the round's last job, included.
    void observe_merge(double seconds);

    // Every metric in Prometheus' text exposition format, version 0.0.4.
    std::string scrape();
    static constexpr const char* kContentType =
        "text/plain; version=0.0.4; charset=utf-8";

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace aliquot
