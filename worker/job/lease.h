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
// Ignored also answers a result for a lease another session holds ("not your lease"):
// the holder's lease stays and its own result still merges.
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

// Thrown by a link when the coordinator refuses the worker's credentials (a missing or
// wrong worker token, or the client's): retrying cannot help, so the worker stops and
// says why (docs/SECURITY.md).
class LinkRefused : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Thrown by any call but register_worker when the coordinator does not know the worker's
// session (it restarted since the worker registered, or the session was never issued):
// the worker registers again, with its threads, then asks again. Nothing else changed.
class WorkerUnknown : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// What register_worker hands a worker: the session every later call carries, and how
// long a lease lasts. The session is an unguessable token (128 random bits, hex): the
// coordinator knows the worker by it, not by its name, so a caller that only knows a
// worker's name (or a lease id) cannot act for it (docs/SECURITY.md, "Lease ownership").
struct Registration {
    std::string session;
    uint32_t lease_ms = 0;
};

// Every call but register_worker carries the session; one the coordinator does not know
// throws WorkerUnknown. A lease belongs to the session that leased it: complete, renew,
// abandon and fail from any other session change nothing.
class WorkerLink {
public:
    virtual ~WorkerLink() = default;
    virtual Registration register_worker(const std::string& name, uint32_t threads) = 0;
    virtual std::optional<LeaseGrant> lease(const std::string& session,
                                            std::chrono::milliseconds wait) = 0;
    virtual CompleteOutcome complete(const std::string& session, uint64_t lease_id,
                                     const SampleJobResult& result) = 0;
    // complete, then, when the result merged, lease the next job (waiting up to `wait`)
    // into `next`: one round trip a job where a link can make it one (GrpcLink). No lease
    // leaves `next` empty, and the worker asks with lease() as usual; the outcome is the
    // result's either way.
    virtual CompleteOutcome complete_and_lease(const std::string& session,
                                               uint64_t lease_id,
                                               const SampleJobResult& result,
                                               std::chrono::milliseconds wait,
                                               std::optional<LeaseGrant>& next) {
        const CompleteOutcome outcome = complete(session, lease_id, result);
        next.reset();
        if (outcome.status != CompleteStatus::Merged) return outcome;
        try {
            next = lease(session, wait);
        } catch (const WorkerUnknown&) {
        }
        return outcome;
    }
    virtual std::optional<std::string> fetch_scene(const std::string& session,
                                                   const std::string& hash) = 0;
    // False when the lease is not (or no longer) this session's.
    virtual bool renew(const std::string& session, uint64_t lease_id) = 0;
    // Gives a lease back untraced (the worker is stopping): re-issued at once, no fault.
    virtual bool abandon(const std::string& session, uint64_t lease_id) = 0;
    // The worker cannot trace the lease (its scene does not load, tracing threw), for
    // `reason`: the job goes to another worker, and the failure counts against the job
    // and the worker (docs/FARM.md). False when the lease is no longer the worker's.
    virtual bool fail(const std::string& session, uint64_t lease_id,
                      const std::string& reason) = 0;
};

}  // namespace aliquot
