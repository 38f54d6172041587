// For the api room's tests: the tokens their coordinators run with, and call contexts
// that carry one (a context without a token is refused, as it is in production).
#pragma once

#include <grpcpp/grpcpp.h>

#include "access.h"
#include "grpc_server.h"

namespace aliquot::testing {

inline const Tokens kTestTokens{"client-token-for-tests-0123",
                                "worker-token-for-tests-0123"};

inline GrpcSecurity test_security() { return {kTestTokens, "", ""}; }

// A call context carrying `role`'s token.
class TokenContext : public grpc::ClientContext {
public:
    explicit TokenContext(Role role) {
        AddMetadata(
            "authorization",
            "Bearer " + (role == Role::Client ? kTestTokens.client : kTestTokens.worker));
    }
};

}  // namespace aliquot::testing
