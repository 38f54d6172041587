// The coordinator's gRPC face: the client and worker services, thin over Coordinator.
#pragma once

#include <memory>
#include <string>

#include "coordinator.h"

namespace grpc {
class Server;
}

namespace aliquot {

class GrpcServer {
public:
    // Listens on `address` (host:port); throws std::runtime_error if it cannot.
    GrpcServer(Coordinator& coordinator, const std::string& address);
    ~GrpcServer();
    int port() const { return port_; }
    void shutdown();

private:
    struct Services;
    std::unique_ptr<Services> services_;
    std::unique_ptr<grpc::Server> server_;
    int port_ = 0;
};

}  // namespace aliquot
