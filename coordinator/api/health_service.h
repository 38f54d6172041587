// grpc.health.v1.Health, the coordinator's own: what Kubernetes' gRPC probes and load
// balancers ask, without a token. gRPC's built-in service keeps every Watch stream
// however many a peer opens; this one holds at most a fixed number and refuses the rest
// with RESOURCE_EXHAUSTED (docs/SECURITY.md, "gRPC limits"). Callback API: an open
// Watch holds no server thread.
#pragma once

#include <grpc/health/v1/health.grpc.pb.h>

#include <map>
#include <mutex>
#include <set>
#include <string>
#include <vector>

namespace aliquot {

class HealthService final : public grpc::health::v1::Health::CallbackService {
public:
    // `services`: the names answered SERVING ("" is the server as a whole).
    HealthService(std::vector<std::string> services, int max_watches);
    // NOT_SERVING for every service from now on, told to every open Watch. Idempotent.
    void stop_serving();
    // Watch streams open now.
    int watches();

    grpc::ServerUnaryReactor* Check(
        grpc::CallbackServerContext* ctx, const grpc::health::v1::HealthCheckRequest* req,
        grpc::health::v1::HealthCheckResponse* reply) override;
    grpc::ServerWriteReactor<grpc::health::v1::HealthCheckResponse>* Watch(
        grpc::CallbackServerContext* ctx,
        const grpc::health::v1::HealthCheckRequest* req) override;

private:
    class Watcher;
    using Status = grpc::health::v1::HealthCheckResponse::ServingStatus;
    Status status_of(const std::string& service) const;  // under mutex_
    void forget(Watcher* w);

    const std::set<std::string> services_;
    const int max_watches_;
    std::mutex mutex_;  // taken before any Watcher's own
    bool serving_ = true;
    std::set<Watcher*> watchers_;
};

}  // namespace aliquot
