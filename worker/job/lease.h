// Lease and WorkerLink: what a worker holds while it traces a job, and the calls it makes
// to a coordinator. The link is gRPC for a remote worker and a direct call for the
// embedded render's local threads; the worker loop cannot tell them apart.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include "sample_job.h"

namespace aliquot {

struct LeaseGrant {
    uint64_t lease_id = 0;
    std::string render_id;
    std::string scene_hash;
    RenderGeometry geometry;
    SampleJob job;
    uint32_t lease_ms = 0;
};

// A plain C++ enum rather than v1::CompleteStatus: the embedded render's threads complete
// jobs by direct call and never link protobuf. proto/wire.h maps it for gRPC.
enum class CompleteStatus { Merged, Ignored, Rejected };
struct CompleteOutcome {
    CompleteStatus status;
    std::string message;
};

// Thrown by a link when the coordinator cannot be reached; the worker backs off and
// retries.
class LinkUnavailable : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Thrown by a link's lease() when the coordinator does not know the worker (it restarted
// since the worker registered): the worker registers again, then asks again.
class WorkerUnknown : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

class WorkerLink {
public:
    virtual ~WorkerLink() = default;
    // Returns the lease duration in milliseconds.
    virtual uint32_t register_worker(const std::string& name, uint32_t threads) = 0;
    virtual std::optional<LeaseGrant> lease(const std::string& worker,
                                            std::chrono::milliseconds wait) = 0;
    virtual CompleteOutcome complete(const std::string& worker, uint64_t lease_id,
                                     const SampleJobResult& result) = 0;
    virtual std::optional<std::string> fetch_scene(const std::string& hash) = 0;
    virtual bool renew(const std::string& worker, uint64_t lease_id) = 0;
    // Gives a lease back untraced (the worker is stopping): re-issued at once, no fault.
    virtual bool abandon(const std::string& worker, uint64_t lease_id) = 0;
    // The worker cannot trace the lease (its scene does not load, tracing threw), for
    // `reason`: the job goes to another worker, and the failure counts against the job
    // and the worker (docs/FARM.md). False when the lease is no longer the worker's.
    virtual bool fail(const std::string& worker, uint64_t lease_id,
                      const std::string& reason) = 0;
};

}  // namespace aliquot
