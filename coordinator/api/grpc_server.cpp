#include "grpc_server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/server_builder_option.h>
#include <grpcpp/resource_quota.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "aliquot.grpc.pb.h"
#include "farm_log.h"
#include "grpc_client_service.h"
#include "grpc_worker_service.h"
#include "health_service.h"
#include "listener_watchdog.h"
#include "open_file_limit.h"

namespace aliquot {

// One server's services: a server started again by the watchdog gets new ones.
struct GrpcServer::Services {
    Tokens tokens;
    std::unique_ptr<grpc::Service> client;
    std::unique_ptr<grpc::Service> worker;
    HealthService health;
    Services(Coordinator& c, Tokens t, FarmMetrics* metrics, const GrpcLimits& limits)
        : tokens(std::move(t)),
          client(make_client_service(c, tokens, limits)),
          worker(make_worker_service(c, tokens, metrics, limits)),
          // "" is the server as a whole, what a probe that names no service asks about.
          health({"", v1::ClientService::service_full_name(),
                  v1::WorkerService::service_full_name()},
                 limits.max_health_watches) {}
};

namespace {

std::shared_ptr<grpc::ServerCredentials> server_credentials(const GrpcSecurity& s) {
    if (s.tls_cert_pem.empty()) return grpc::InsecureServerCredentials();
    grpc::SslServerCredentialsOptions options;
    options.pem_key_cert_pairs.push_back({s.tls_key_pem, s.tls_cert_pem});
    return grpc::SslServerCredentials(options);
}

// Whether this builder's server has reflection. Loading libgrpc++_reflection adds its
// plugin to every ServerBuilder of the process (a static initializer), so the option
// removes it, and adds one back only when asked to.
class ReflectionOption final : public grpc::ServerBuilderOption {
public:
    explicit ReflectionOption(bool on) : on_(on) {}
    void UpdateArguments(grpc::ChannelArguments*) override {}
    void UpdatePlugins(
        std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
        auto reflection =
            std::make_unique<grpc::reflection::ProtoServerReflectionPlugin>();
        const std::string name = reflection->name();
        std::erase_if(*plugins, [&](const auto& p) { return p && p->name() == name; });
        if (on_) plugins->push_back(std::move(reflection));
    }

private:
    bool on_;
};

}  // namespace

GrpcServer::GrpcServer(Coordinator& coordinator, const std::string& address,
                       GrpcSecurity security, GrpcOptions options, GrpcLimits limits)
    : coordinator_(coordinator),
      security_(std::move(security)),
      options_(options),
      limits_(limits) {
    check_tokens(security_.tokens);
    if (security_.tls_cert_pem.empty() != security_.tls_key_pem.empty())
        throw std::invalid_argument("gRPC: TLS needs both a certificate and its key");
    // Every connection holds a descriptor: the more a flood needs to exhaust them, the
    // better (the watchdog below answers the rest).
    raise_open_file_limit();
    std::lock_guard lock(mutex_);
    listen(address);
    host_ = address.substr(0, address.rfind(':'));
    if (limits_.watchdog_failures <= 0) return;
    // Asked first of a port just opened: where the probe cannot tell (no /proc/net), a
    // listener must not be started again for ever.
    if (!reachable()) {
        log_farm_error("cannot check that gRPC's port " + std::to_string(port_.load()) +
                           " accepts connections here; no listener watchdog",
                       "listener_watchdog_off");
        return;
    }
    watchdog_ = std::make_unique<ListenerWatchdog>(
        limits_.watchdog_period, limits_.watchdog_failures,
        [this] { return reachable(); }, [this] { listen_again(); });
}

void GrpcServer::listen(const std::string& address) {
    const GrpcLimits& limits = limits_;
    services_ = std::make_unique<Services>(coordinator_, security_.tokens,
                                           options_.metrics, limits);
    // gRPC's own health service is off: ours (health_service.h) caps Watch streams.
    grpc::EnableDefaultHealthCheckService(false);
    grpc::ServerBuilder builder;
    builder.SetOption(std::make_unique<ReflectionOption>(options_.reflection));
    int port = 0;
    builder.AddListeningPort(address, server_credentials(security_), &port);
    builder.RegisterService(services_->client.get());
    builder.RegisterService(services_->worker.get());
    builder.RegisterService(&services_->health);
    // What a peer can make the server hold (docs/SECURITY.md, "gRPC limits"): threads
    // (a call finding none is refused), buffers, streams per connection, and how long
    // a connection that says nothing or has nothing open is kept.
    grpc::ResourceQuota quota("aliquot-grpc");
    quota.SetMaxThreads(limits.max_threads);
    quota.Resize(limits.max_memory_bytes);
    builder.SetResourceQuota(quota);
    // No SO_REUSEPORT (gRPC's default): with it, sockets of this or another process
    // could share the port, the kernel handing each a share of new connections, a deaf
    // one too, where the watchdog's one probe might not land. Without it a second
    // coordinator on the same port fails to start instead of sharing it.
    builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
    builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS,
                               limits.max_streams_per_connection);
    builder.AddChannelArgument(GRPC_ARG_SERVER_HANDSHAKE_TIMEOUT_MS,
                               int(limits.handshake_timeout.count()));
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS,
                               int(limits.max_idle.count()));
    // Keepalive matched with the workers' channel settings (worker/grpc_link.cpp).
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 20000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
    builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS,
                               10000);
    builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, 0);
    server_ = builder.BuildAndStart();
    if (!server_ || port == 0) {
        server_.reset();
        throw std::runtime_error("cannot listen on " + address);
    }
    port_ = port;
    if (!serving_) services_->health.stop_serving();
}

bool GrpcServer::reachable() {
    // Accepted, not only queued: what gRPC 1.51 stops doing after a failed accept.
    // A wildcard listens on loopback too (gRPC's "[::]" is dual-stack, or falls back
    // to 0.0.0.0 where IPv6 is off).
    std::string host = host_;
    if (host.empty() || host == "0.0.0.0" || host == "[::]" || host == "[::0]")
        host = "127.0.0.1";
    if (host.size() > 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    return accepts_connections(
        host, port_.load(),
        std::max(limits_.watchdog_period, std::chrono::milliseconds(1000)));
}

void GrpcServer::listen_again() {
    std::lock_guard lock(mutex_);
    if (stopped_) return;
    log_farm_error(
        "gRPC on port " + std::to_string(port_.load()) +
            " accepts no new connections (out of file descriptors?); listening "
            "again",
        "listener_deaf");
    // Calls in progress are cut off: their clients and workers retry on a new
    // connection.
    server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
    server_.reset();
    services_.reset();
    try {
        listen(host_ + ":" + std::to_string(port_.load()));
        ++restarts_;
    } catch (const std::exception& e) {
        // Up but deaf is worse than down: a supervisor restarts a process that exits.
        log_farm_error("cannot listen on port " + std::to_string(port_.load()) +
                           " again (" + e.what() +
                           "); exiting so that a supervisor restarts the coordinator",
                       "listener_failed");
        std::fflush(stderr);
        std::_Exit(75);
    }
}

int GrpcServer::restarts() {
    std::lock_guard lock(mutex_);
    return restarts_;
}

GrpcServer::~GrpcServer() { shutdown(); }

void GrpcServer::stop_serving() {
    // NOT_SERVING for every service, and no later change.
    std::lock_guard lock(mutex_);
    serving_ = false;
    if (services_) services_->health.stop_serving();
}

void GrpcServer::shutdown() {
    stop_serving();
    // First the watchdog, which could otherwise start the server again.
    watchdog_.reset();
    std::lock_guard lock(mutex_);
    stopped_ = true;
    if (server_) {
        server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
        server_.reset();
    }
}

}  // namespace aliquot
