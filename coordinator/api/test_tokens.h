// For the api room's tests: the tokens their coordinators run with, and call contexts
// that carry one (a context without a token is refused, as it is in production).
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <grpcpp/create_channel_posix.h>
#include <grpcpp/grpcpp.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

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

// A channel of one connection to 127.0.0.1:port made from `source` (any address of 127/8
// is this host): a second client address on one machine, for what one address may hold.
// gRPC never connects it again; with `args` a caller can keep its window from growing.
inline std::shared_ptr<grpc::Channel> channel_from(
    const char* source, int port, const grpc::ChannelArguments& args = {}) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in from{};
    from.sin_family = AF_INET;
    ::inet_pton(AF_INET, source, &from.sin_addr);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(uint16_t(port));
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(fd, reinterpret_cast<sockaddr*>(&from), sizeof from) != 0 ||
        ::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to) != 0 ||
        ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK) != 0) {
        ::close(fd);
        return nullptr;
    }
    return grpc::CreateCustomInsecureChannelFromFd("127.0.0.1:" + std::to_string(port),
                                                   fd, args);
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
