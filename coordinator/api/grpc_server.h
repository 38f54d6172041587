// The coordinator's gRPC face: the client and worker services, thin over Coordinator.
// Every call first shows its role's token (docs/SECURITY.md). Beside them, without a
// token: the standard health service (grpc.health.v1.Health, what Kubernetes' gRPC
// probes call) and, when asked for, server reflection (docs/SECURITY.md says why).
#pragma once

#include <memory>
#include <string>

#include "access.h"
#include "coordinator.h"
#include "metrics.h"

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

struct GrpcOptions {
    // Where the worker service's Lease and merge latencies go; none when null.
    FarmMetrics* metrics = nullptr;
    // Serve grpc.reflection.v1alpha.ServerReflection (grpcurl and grpc_cli list and
    // describe the services through it). Off by default: each reflection stream holds a
    // server thread while open, and it needs no token.
    bool reflection = false;
};

class GrpcServer {
public:
    // Listens on `address` (host:port); throws std::runtime_error if it cannot, and
    // std::invalid_argument for unusable security settings. Health answers SERVING for
    // "" (the whole server), aliquot.v1.ClientService and aliquot.v1.WorkerService.
    GrpcServer(Coordinator& coordinator, const std::string& address,
               GrpcSecurity security, GrpcOptions options = {});
    ~GrpcServer();
    int port() const { return port_; }
    // Health answers NOT_SERVING from now on, for every service, while calls are still
    // served: the first step of shutting down, so that probes and load balancers turn
    // away before the port closes. Idempotent.
    void stop_serving();
    // stop_serving(), then stops: calls still running get 2 s to end. Idempotent.
    void shutdown();

private:
    struct Services;
    std::unique_ptr<Services> services_;
    std::unique_ptr<grpc::Server> server_;
    int port_ = 0;
};

}  // namespace aliquot
