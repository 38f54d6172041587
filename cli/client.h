// ClientConnection: the CLI's channel to a coordinator's client service. Turns gRPC
// failures into one-line CommandErrors ("cannot reach coordinator at ADDR").
#pragma once

#include <memory>
#include <string>

#include <functional>

#include <grpcpp/grpcpp.h>
#include "aliquot.grpc.pb.h"
#include "channel.h"
#include "coordinator.h"

namespace aliquot::cli {

class ClientConnection {
public:
    // Waits up to the endpoint's connect_timeout for the coordinator to answer.
    explicit ClientConnection(CoordinatorEndpoint endpoint);
    v1::ClientService::Stub& stub() { return *stub_; }
    // A context whose deadline is `seconds` from now, carrying the client token.
    std::unique_ptr<grpc::ClientContext> context(int seconds = 30) const;
    // Adds the client token to a context made elsewhere (a stream without a deadline).
    void authorize(grpc::ClientContext& ctx) const { add_token(ctx, endpoint_); }
    // Throws CommandError for a failed call; `what` names the call for the message.
    void check(const grpc::Status& status, const std::string& what) const;
    const std::string& address() const { return endpoint_.address; }

private:
    std::string waited() const;  // " after waiting N s", for an unreachable coordinator

    CoordinatorEndpoint endpoint_;
    bool connected_ = false;  // the port answered within the connect timeout
    std::unique_ptr<v1::ClientService::Stub> stub_;
};

// Human-readable one-line progress of a render, e.g. for status and watch.
std::string describe(const RenderInfo& info);

}  // namespace aliquot::cli

namespace aliquot::cli {

// Streams the render's EXR into `path` (written whole, then renamed into place).
void fetch_image(ClientConnection& connection, const std::string& id,
                 const std::string& path, bool aovs);
// Follows a render until it finishes, calling `update` for every state the coordinator
// sends; returns the last one. Replies arrive as v1::RenderInfo and are read with the
// api room's from_proto (render_proto.h), the same conversion the server writes with.
RenderInfo follow(ClientConnection& connection, const std::string& id,
                  const std::function<void(const RenderInfo&)>& update);
// Throws CommandError (exit status 1) unless the render followed to its end is done: a
// script waiting on `watch` or `submit --wait` must see a failed or cancelled render.
void check_done(const RenderInfo& last);

}  // namespace aliquot::cli
