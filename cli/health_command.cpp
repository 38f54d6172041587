// aliquot health: asks a coordinator's gRPC health service (grpc.health.v1.Health/Check),
// as Kubernetes' gRPC probes and grpc_health_probe do: no token, one call, exit 0 only
// for SERVING. What the image's healthcheck runs for a coordinator
// (deploy/healthcheck.sh), instead of listing renders on every probe.
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>

#include <grpc/health/v1/health.grpc.pb.h>
#include "channel.h"
#include "commands.h"
#include "endpoint_options.h"

namespace aliquot::cli {

namespace {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

struct HealthCommand {
    std::string address;  // empty: $ALIQUOT_COORDINATOR, else kDefaultCoordinator
    std::string service;  // "": the server as a whole
    std::string tls_ca;   // empty: plaintext
    double timeout_seconds = 5;

    void run() {
        if (!(timeout_seconds > 0)) throw UsageError("--timeout: must be positive");
        // The address as every client command reads it; no token: health needs none
        // (docs/SECURITY.md).
        EndpointOptions where;
        where.address = address;
        CoordinatorEndpoint endpoint;
        endpoint.address = where.effective_address();
        if (!tls_ca.empty()) endpoint.tls_ca_pem = read_tls_ca(tls_ca);
        const auto stub = grpc::health::v1::Health::NewStub(
            grpc::CreateChannel(endpoint.address, channel_credentials(endpoint)));
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::milliseconds(int64_t(timeout_seconds * 1000)));
        HealthCheckRequest req;
        req.set_service(service);
        HealthCheckResponse reply;
        const grpc::Status status = stub->Check(&ctx, req, &reply);
        const std::string name =
            service.empty() ? endpoint.address : endpoint.address + " " + service;
        if (!status.ok())
            throw CommandError("health of " + name + ": " + status.error_message());
        const std::string& serving =
            HealthCheckResponse::ServingStatus_Name(reply.status());
        std::printf("%s\n", serving.c_str());
        if (reply.status() != HealthCheckResponse::SERVING)
            throw CommandError(name + " is " + serving);
    }
};

}  // namespace

void register_health(CLI::App& app) {
    auto c = std::make_shared<HealthCommand>();
    CLI::App* cmd = app.add_subcommand(
        "health", "ask a coordinator's gRPC health service, as a probe does (no token)");
    cmd->add_option("--coordinator", c->address,
                    std::string("coordinator address host:port (default: "
                                "$ALIQUOT_COORDINATOR, else ") +
                        kDefaultCoordinator + ")");
    cmd->add_option("--service", c->service,
                    "aliquot.v1.ClientService or aliquot.v1.WorkerService (default: the "
                    "server as a whole)");
    cmd->add_option("--tls-ca", c->tls_ca,
                    "PEM of the CA that signed the coordinator's "
                    "certificate (default: plaintext)");
    cmd->add_option("--timeout", c->timeout_seconds, "seconds to wait for the answer")
        ->capture_default_str();
    cmd->callback([c] { c->run(); });
}

}  // namespace aliquot::cli
