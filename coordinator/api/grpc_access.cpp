// A gRPC call's bearer token, checked against its service's role (grpc_access.h).
#include "grpc_access.h"

#include <string_view>

namespace aliquot {

grpc::Status admit(const grpc::ServerContext* ctx, const Tokens& tokens, Role role) {
    const auto& metadata = ctx->client_metadata();
    const auto header = metadata.find("authorization");
    const std::string_view value =
        header == metadata.end()
            ? std::string_view()
            : std::string_view(header->second.data(), header->second.size());
    const Access access = check_access(tokens, bearer_token(value), role);
    if (access == Access::Granted) return grpc::Status::OK;
    return {access == Access::Forbidden ? grpc::StatusCode::PERMISSION_DENIED
                                        : grpc::StatusCode::UNAUTHENTICATED,
            access_message(access, role)};
}

}  // namespace aliquot
