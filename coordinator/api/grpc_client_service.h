// The gRPC client service (aliquot.v1.ClientService): submit, read, watch, cancel,
// delete and fetch renders, thin over Coordinator. Apart from GrpcServer, which only
// listens and starts it (grpc_server.h), and from the worker service.
#pragma once

#include <memory>

#include "grpc_server.h"

namespace grpc {
class Service;
}

namespace aliquot {

// `tokens` and `limits` outlive the service (GrpcServer::Services holds them); the
// service holds the FetchImage and Watch places (GrpcLimits) and its stream watchdog.
std::unique_ptr<grpc::Service> make_client_service(Coordinator& c, const Tokens& tokens,
                                                   const GrpcLimits& limits);

}  // namespace aliquot
