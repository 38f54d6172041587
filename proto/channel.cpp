#include "channel.h"

#include <grpcpp/grpcpp.h>

namespace aliquot {

std::shared_ptr<grpc::ChannelCredentials> channel_credentials(
    const CoordinatorEndpoint& endpoint) {
    if (endpoint.tls_ca_pem.empty()) return grpc::InsecureChannelCredentials();
    grpc::SslCredentialsOptions options;
    options.pem_root_certs = endpoint.tls_ca_pem;
    return grpc::SslCredentials(options);
}

void add_token(grpc::ClientContext& context, const CoordinatorEndpoint& endpoint) {
    // Metadata rather than call credentials: gRPC sends call credentials over TLS only,
    // and a coordinator on loopback may serve plaintext.
    if (!endpoint.token.empty())
        context.AddMetadata("authorization", "Bearer " + endpoint.token);
}

}  // namespace aliquot
