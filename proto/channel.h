// How a client or a worker reaches the coordinator: its address, the bearer token every
// call carries, and the CA that signed its TLS certificate when it serves TLS
// (docs/SECURITY.md).
#pragma once

#include <chrono>
#include <memory>
#include <string>

namespace grpc {
class ChannelCredentials;
class ClientContext;
}  // namespace grpc

namespace aliquot {

struct CoordinatorEndpoint {
    std::string address = "127.0.0.1:7070";
    std::string token;       // sent as `authorization: Bearer TOKEN`
    std::string tls_ca_pem;  // empty: plaintext
    // How long a client waits for a coordinator that is starting before its first call
    // (gRPC's wait-for-ready, bounded): `aliquot coordinator & aliquot submit` works.
    // Workers retry for as long as they run and ignore it.
    std::chrono::milliseconds connect_timeout{0};
};

// TLS checked against the endpoint's CA when it has one, plaintext otherwise.
std::shared_ptr<grpc::ChannelCredentials> channel_credentials(
    const CoordinatorEndpoint& endpoint);

// Adds the endpoint's token to a call.
void add_token(grpc::ClientContext& context, const CoordinatorEndpoint& endpoint);

}  // namespace aliquot
