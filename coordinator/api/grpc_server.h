// The coordinator's gRPC face: the client and worker services, thin over Coordinator.
// Every call first shows its role's token (docs/SECURITY.md).
#pragma once

#include <memory>
#include <string>

#include "access.h"
#include "coordinator.h"

namespace grpc {
class Server;
}

namespace aliquot {

// Who may call (each service's role token) and, when a certificate is given, TLS.
struct GrpcSecurity {
    Tokens tokens;             // both set, and different
    std::string tls_cert_pem;  // empty: plaintext
    std::string tls_key_pem;
};

class GrpcServer {
public:
    // Listens on `address` (host:port); throws std::runtime_error if it cannot, and
    // std::invalid_argument for unusable security settings.
    GrpcServer(Coordinator& coordinator, const std::string& address,
               GrpcSecurity security);
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
