#include "client.h"

#include <grpc/support/log.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <thread>

#include "commands.h"
#include "error_metric.h"
#include "render_proto.h"

namespace aliquot::cli {

namespace {

// gRPC core's own lines ("E1204 ... ssl_transport_security.cc:1501] Handshake failed
// ...", once per retry) are not for the user of a client command: check() says in one
// line what failed and what to do. The last is kept for the reason it names, which the
// call's status often lacks.
std::mutex grpc_line_mutex;
std::string last_grpc_line;

void keep_grpc_line(gpr_log_func_args* args) {
    if (!args->message) return;
    std::lock_guard lock(grpc_line_mutex);
    last_grpc_line = args->message;
}

std::string lowercase(std::string s) {
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// What a coordinator (or whatever answers at its address) says, as one line of bounded
// length: no control character of its can end the line or move the terminal's cursor.
std::string one_line(const std::string& text) {
    constexpr size_t kLongest = 300;
    std::string out;
    for (const char c : text.substr(0, kLongest)) {
        const auto u = static_cast<unsigned char>(c);
        out += u < 0x20 || u == 0x7f ? '?' : c;
    }
    if (text.size() > kLongest) out += "...";
    return out;
}

}  // namespace

ClientConnection::ClientConnection(CoordinatorEndpoint endpoint)
    : endpoint_(std::move(endpoint)) {
    gpr_set_log_function(keep_grpc_line);
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

// Why the coordinator could not be reached, and what to do, from gRPC's reason (the
// call's status and gRPC's last line): a port nobody listens on, a name that does not
// resolve, a TLS handshake that failed and why.
static std::string unreachable_hint(const grpc::Status& status,
                                    const std::string& address, bool using_tls) {
    std::string reason = lowercase(status.error_message());
    {
        std::lock_guard lock(grpc_line_mutex);
        reason += " " + lowercase(last_grpc_line);
    }
    const auto says = [&](const char* text) {
        return reason.find(text) != std::string::npos;
    };
    if (says("connection refused"))
        return ": nothing listens there; start the coordinator (aliquot coordinator "
               "--grpc " +
               address +
               ") or name the right address (--coordinator, ALIQUOT_COORDINATOR)";
    if (says("dns") || says("name or service not known") || says("resolution"))
        return ": its name does not resolve; check --coordinator (or "
               "ALIQUOT_COORDINATOR)";
    if (using_tls && (says("wrong version number") || says("packet length too long") ||
                      says("http_request")))
        return ": it does not serve TLS; drop --tls-ca, or start it with --tls-cert and "
               "--tls-key";
    if (using_tls && says("certificate"))
        return ": its TLS certificate is not signed by the --tls-ca CA or not issued for "
               "this address; pass the CA that signed it, and an address the certificate "
               "names";
    if (using_tls && (says("ssl") || says("tls") || says("handshake")))
        return ": the TLS handshake failed; is the coordinator's certificate signed by "
               "the "
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
    const std::string& address = endpoint_.address;
    const std::string token_advice =
        "; this call needs the client token: pass the client.token of the "
        "coordinator's --data directory with --token-file or ALIQUOT_TOKEN";
    switch (status.error_code()) {
        case grpc::StatusCode::CANCELLED:  // the coordinator stopping ends its calls
            throw CommandError("the coordinator at " + address + " stopped answering (" +
                               what + "); is it still running? (it ended the call)");
        case grpc::StatusCode::UNAVAILABLE:
        case grpc::StatusCode::DEADLINE_EXCEEDED:
            if (connected_)
                throw CommandError(
                    "the coordinator at " + address + " stopped answering (" + what +
                    "); is it still running? (" + one_line(status.error_message()) + ")");
            throw CommandError(
                "cannot reach coordinator at " + address + " (" + what + ")" + waited() +
                unreachable_hint(status, address, !endpoint_.tls_ca_pem.empty()));
        case grpc::StatusCode::UNAUTHENTICATED:
            throw CommandError(what + ": the coordinator at " + address +
                               " does not accept this token" + token_advice);
        case grpc::StatusCode::PERMISSION_DENIED:
            throw CommandError(what + ": the coordinator at " + address +
                               " refused the worker token" + token_advice);
        default:
            throw CommandError(what + ": " + one_line(status.error_message()));
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
    if (i.mean_bias) {  // as `aliquot compare` says it: E hides an image too dark
        ErrorMetrics m;
        m.mean_abs = i.error_vs_reference;
        m.mean_bias = *i.mean_bias;
        m.mean_bias_se = i.mean_bias_se.value_or(std::nan(""));
        s += "  bias " + mean_bias_text(m);
    }
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
    const std::string tmp = path + ".part";
    // The coordinator refuses a fetch past its places (RESOURCE_EXHAUSTED, before any
    // byte): a render just done is served from memory until its file is written, one
    // such fetch an address at a time, so a client fetching several renders at once
    // waits its turn rather than failing. Bounded: ~2 minutes of refusals.
    auto pause = std::chrono::milliseconds(50);
    for (int refusals = 0;; ++refusals) {
        auto ctx = c.context(300);
        auto reader = c.stub().FetchImage(ctx.get(), req);
        size_t received = 0;
        {
            std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
            if (!out) throw CommandError("--out: cannot write " + path);
            v1::FileChunk chunk;
            while (reader->Read(&chunk)) {
                out.write(chunk.data().data(), std::streamsize(chunk.data().size()));
                received += chunk.data().size();
            }
            out.close();
            if (!out) {  // a full disk: never rename a truncated file into place
                reader->Finish();
                std::filesystem::remove(tmp);
                throw CommandError("--out: cannot write " + path);
            }
        }
        const grpc::Status status = reader->Finish();
        if (!status.ok()) std::filesystem::remove(tmp);
        if (status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED &&
            received == 0 && refusals < 60) {
            std::this_thread::sleep_for(pause);
            pause = std::min(pause * 2, std::chrono::milliseconds(2000));
            continue;
        }
        c.check(status, "fetch " + id);
        std::filesystem::rename(tmp, path);
        return;
    }
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
