#include "client.h"

#include <cctype>
#include <cstdio>
#include <thread>

#include "commands.h"
#include "render_proto.h"

namespace aliquot::cli {

ClientConnection::ClientConnection(CoordinatorEndpoint endpoint)
    : endpoint_(std::move(endpoint)) {
    grpc::ChannelArguments args;
    // While waiting for a coordinator that is starting, try again every 100 ms at first
    // and never more than a second apart (gRPC's default backoff grows to minutes).
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
    args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 100);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
    auto channel = grpc::CreateCustomChannel(endpoint_.address,
                                             channel_credentials(endpoint_), args);
    // Wait-for-ready for the connection only, not for each call: once the timeout is
    // spent the first call fails at once with gRPC's own reason (refused, TLS handshake),
    // which check() turns into the one line the user reads; and a coordinator that dies
    // later fails a call at once rather than after its whole deadline.
    connected_ = channel->WaitForConnected(std::chrono::system_clock::now() +
                                           endpoint_.connect_timeout);
    stub_ = v1::ClientService::NewStub(channel);
}

std::unique_ptr<grpc::ClientContext> ClientConnection::context(int seconds) const {
    auto ctx = std::make_unique<grpc::ClientContext>();
    ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(seconds));
    add_token(*ctx, endpoint_);
    return ctx;
}

// gRPC reports a failed TLS handshake as an unreachable coordinator. Whether TLS is the
// likely cause, and what to do about it, for the one line the user reads.
static std::string tls_hint(const grpc::Status& status, bool using_tls) {
    std::string message = status.error_message();
    for (char& c : message) c = char(std::tolower(static_cast<unsigned char>(c)));
    const bool handshake = message.find("ssl") != std::string::npos ||
                           message.find("tls") != std::string::npos ||
                           message.find("handshake") != std::string::npos ||
                           message.find("certificate") != std::string::npos;
    if (using_tls && handshake)
        return "; TLS handshake failed: is the coordinator's certificate signed by the "
               "--tls-ca CA and issued for this address, and does the coordinator serve "
               "TLS?";
    if (using_tls) return "";
    // A plaintext client that reaches a TLS port sees its connection closed.
    return "; if the coordinator serves TLS (--tls-cert), pass --tls-ca with its CA";
}

std::string ClientConnection::waited() const {
    char seconds[32];
    // Tenths: what the token file took is already gone from the timeout.
    std::snprintf(seconds, sizeof seconds, "%.1f",
                  double(endpoint_.connect_timeout.count()) / 1000.0);
    return std::string(" after waiting ") + seconds + " s (--connect-timeout)";
}

void ClientConnection::check(const grpc::Status& status, const std::string& what) const {
    if (status.ok()) return;
    switch (status.error_code()) {
        case grpc::StatusCode::UNAVAILABLE:
        case grpc::StatusCode::DEADLINE_EXCEEDED:
            throw CommandError("cannot reach coordinator at " + endpoint_.address + " (" +
                               what + ")" + (connected_ ? "" : waited()) +
                               tls_hint(status, !endpoint_.tls_ca_pem.empty()));
        default:
            throw CommandError(what + ": " + status.error_message());
    }
}

std::string describe(const RenderInfo& i) {
    char line[512];
    const double pct = i.samples_planned
                           ? 100.0 * double(i.samples_done) / double(i.samples_planned)
                           : 0.0;
    // "queued (position 2)": which of the queued renders a worker takes next.
    std::string state(to_string(i.state));
    if (i.state == RenderState::Queued && i.queue_position > 0)
        state += " (position " + std::to_string(i.queue_position) + ")";
    std::snprintf(
        line, sizeof line,
        "%s  %-9s %-10s %-16s %ux%u  round %u  %llu/%llu samples (%.1f%%)  %.0f "
        "samples/s  %.1fs  err~%s",
        i.id.c_str(), state.c_str(), i.method.c_str(), i.scene_name.c_str(), i.width,
        i.height, i.rounds_done, (unsigned long long)i.samples_done,
        (unsigned long long)i.samples_planned, pct, i.samples_per_second, i.seconds,
        i.error_estimate >= 0 ? std::to_string(i.error_estimate).c_str() : "-");
    std::string s = line;
    if (i.error_vs_reference >= 0)
        s += "  E(ref)=" + std::to_string(i.error_vs_reference);
    if (i.priority != 0) s += "  priority " + std::to_string(i.priority);
    if (!i.name.empty()) s += "  name: " + i.name;  // printable: the coordinator checks
    if (!i.error.empty()) s += "  error: " + i.error;
    return s;
}

}  // namespace aliquot::cli

#include <filesystem>
#include <fstream>

namespace aliquot::cli {

void fetch_image(ClientConnection& c, const std::string& id, const std::string& path,
                 bool aovs) {
    v1::FetchImageRequest req;
    req.set_id(id);
    req.set_aovs(aovs);
    auto ctx = c.context(300);
    auto reader = c.stub().FetchImage(ctx.get(), req);
    const std::string tmp = path + ".part";
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw CommandError("--out: cannot write " + path);
        v1::FileChunk chunk;
        while (reader->Read(&chunk))
            out.write(chunk.data().data(), std::streamsize(chunk.data().size()));
        out.close();
        if (!out) {  // a full disk: never rename a truncated file into place
            reader->Finish();
            std::filesystem::remove(tmp);
            throw CommandError("--out: cannot write " + path);
        }
    }
    const grpc::Status status = reader->Finish();
    if (!status.ok()) std::filesystem::remove(tmp);
    c.check(status, "fetch " + id);
    std::filesystem::rename(tmp, path);
}

RenderInfo follow(ClientConnection& c, const std::string& id,
                  const std::function<void(const RenderInfo&)>& update) {
    v1::GetRenderRequest req;
    req.set_id(id);
    v1::RenderInfo message;
    RenderInfo info;
    // A watch stream that breaks (coordinator restarting) is resumed until the render
    // ends.
    for (int attempt = 0;; ++attempt) {
        grpc::ClientContext ctx;
        c.authorize(ctx);
        auto reader = c.stub().Watch(&ctx, req);
        while (reader->Read(&message)) {
            info = from_proto(message);
            update(info);
        }
        const grpc::Status status = reader->Finish();
        if (is_terminal(info.state)) return info;
        if (status.ok()) continue;
        if (status.error_code() != grpc::StatusCode::UNAVAILABLE || attempt > 120)
            c.check(status, "watch " + id);
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
}

void check_done(const RenderInfo& last) {
    if (last.state == RenderState::Failed)
        throw CommandError("render " + last.id + " failed: " + last.error);
    if (last.state == RenderState::Cancelled)
        throw CommandError("render " + last.id + " was cancelled");
}

}  // namespace aliquot::cli
