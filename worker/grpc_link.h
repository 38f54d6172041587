// GrpcLink: a worker's WorkerLink to a coordinator over gRPC. Every call has a deadline;
// an unreachable coordinator becomes LinkUnavailable, which the worker loop waits out.
#pragma once

#include <memory>
#include <string>

#include "lease.h"

namespace aliquot {

class GrpcLink : public WorkerLink {
public:
    explicit GrpcLink(const std::string& address);
    ~GrpcLink() override;

    uint32_t register_worker(const std::string& name, uint32_t threads) override;
    std::optional<LeaseGrant> lease(const std::string& worker,
                                    std::chrono::milliseconds wait) override;
    CompleteOutcome complete(const std::string& worker, uint64_t lease_id,
                             const SampleJobResult& result) override;
    std::optional<std::string> fetch_scene(const std::string& hash) override;
    bool renew(const std::string& worker, uint64_t lease_id) override;
    bool abandon(const std::string& worker, uint64_t lease_id) override;
    bool fail(const std::string& worker, uint64_t lease_id,
              const std::string& reason) override;

private:
    struct Stub;
    std::unique_ptr<Stub> stub_;
    std::string address_;
};

}  // namespace aliquot
