// The gRPC worker service (aliquot.v1.WorkerService): register, lease, complete, renew,
// abandon and fail jobs, thin over Coordinator. Apart from GrpcServer, which only listens
// and starts it (grpc_server.h), and from the client service.
#pragma once

#include <memory>

#include "grpc_server.h"

namespace grpc {
class Service;
}

namespace aliquot {

// `tokens` and `limits` outlive the service (GrpcServer::Services holds them); Lease and
// merge latencies go to `metrics` when it is not null.
std::unique_ptr<grpc::Service> make_worker_service(Coordinator& c, const Tokens& tokens,
                                                   FarmMetrics* metrics,
                                                   const GrpcLimits& limits);

}  // namespace aliquot
