// GrpcLink: a worker's WorkerLink to a coordinator over gRPC. Every call has a deadline;
// an unreachable coordinator becomes LinkUnavailable, which the worker loop waits out; a
// refused token becomes LinkRefused, which ends it.
#pragma once

#include <memory>
#include <string>

#include "channel.h"
#include "lease.h"

namespace aliquot {
namespace v1 {
class LeaseReply;
}

class GrpcLink : public WorkerLink {
public:
    explicit GrpcLink(CoordinatorEndpoint endpoint);
    ~GrpcLink() override;

    Registration register_worker(const std::string& name, uint32_t threads) override;
    std::optional<LeaseGrant> lease(const std::string& session,
                                    std::chrono::milliseconds wait) override;
    CompleteOutcome complete(const std::string& session, uint64_t lease_id,
                             const SampleJobResult& result) override;
    CompleteOutcome complete_and_lease(const std::string& session, uint64_t lease_id,
                                       const SampleJobResult& result,
                                       std::chrono::milliseconds wait,
                                       std::optional<LeaseGrant>& next) override;
    std::optional<std::string> fetch_scene(const std::string& session,
                                           const std::string& hash) override;
    bool renew(const std::string& session, uint64_t lease_id) override;
    bool abandon(const std::string& session, uint64_t lease_id) override;
    bool fail(const std::string& session, uint64_t lease_id,
              const std::string& reason) override;

private:
    CompleteOutcome send_result(const std::string& session, uint64_t lease_id,
                                const SampleJobResult& result,
                                std::optional<std::chrono::milliseconds> wait,
                                std::optional<LeaseGrant>* next);
    // The grant in a Lease answer, if any.
    static std::optional<LeaseGrant> grant_of(const v1::LeaseReply& reply);
    // A call's context: a deadline `extra` past the usual, and the worker token.
    std::unique_ptr<grpc::ClientContext> context(
        std::chrono::milliseconds extra = {}) const;

    struct Stub;
    std::unique_ptr<Stub> stub_;
    CoordinatorEndpoint endpoint_;
};

}  // namespace aliquot
