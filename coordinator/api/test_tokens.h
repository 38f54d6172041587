// For the api room's tests: the tokens their coordinators run with, and call contexts
// that carry one (a context without a token is refused, as it is in production).
#pragma once

#include <grpcpp/grpcpp.h>

#include <string>

#include "access.h"
#include "aliquot.grpc.pb.h"
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

// A plaintext channel to a server listening on 127.0.0.1:`port`.
inline std::shared_ptr<grpc::Channel> loopback_channel(int port) {
    return grpc::CreateChannel("127.0.0.1:" + std::to_string(port),
                               grpc::InsecureChannelCredentials());
}

// A uniform 1-spp cornell-box render of `side` x `side` pixels; `scene_json` is the
// scene's self-contained JSON (scene_loader.h).
inline v1::SubmitRequest small_submission(const std::string& scene_json, uint32_t side) {
    v1::SubmitRequest req;
    req.set_scene("cornell-box");
    req.set_scene_json(scene_json);
    req.set_width(side);
    req.set_height(side);
    req.set_strategy_json(R"({"method":"uniform","spp":1})");
    return req;
}

}  // namespace aliquot::testing
