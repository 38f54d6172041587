// The token check every call of the gRPC client and worker services makes first
// (docs/SECURITY.md): shared by both services, each in a file of its own.
#pragma once

#include <grpcpp/grpcpp.h>

#include "access.h"

namespace aliquot {

// Before anything else a call does: the bearer token of its `authorization` metadata must
// be `role`'s (docs/SECURITY.md).
grpc::Status admit(const grpc::ServerContext* ctx, const Tokens& tokens, Role role);

}  // namespace aliquot
