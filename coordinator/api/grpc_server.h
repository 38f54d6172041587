// The coordinator's gRPC face: the client and worker services, thin over Coordinator.
// Every call first shows its role's token (docs/SECURITY.md). Beside them, without a
// token: the standard health service (grpc.health.v1.Health, what Kubernetes' gRPC
// probes call) and, when asked for, server reflection (docs/SECURITY.md says why).
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "access.h"
#include "coordinator.h"
#include "metrics.h"

namespace grpc {
class Server;
}

namespace aliquot {

class ListenerWatchdog;

// Who may call (each service's role token) and, when a certificate is given, TLS.
struct GrpcSecurity {
    Tokens tokens;             // both set, and different
    std::string tls_cert_pem;  // empty: plaintext
    std::string tls_key_pem;
};

// What a peer can make the server hold at once (docs/SECURITY.md, "gRPC limits"). A call
// beyond a cap is answered at once: RESOURCE_EXHAUSTED, or for a Lease an empty reply.
struct GrpcLimits {
    // Server threads in all (gRPC's resource quota): a call that finds none free is
    // refused with RESOURCE_EXHAUSTED rather than given a new thread.
    int max_threads = 512;
    // Buffers of gRPC's connections and calls (its memory quota).
    size_t max_memory_bytes = size_t(1) << 30;
    int max_streams_per_connection = 100;
    // A connection that has sent nothing (not even HTTP/2's preface) is closed after
    // this; one with no call open, after max_idle.
    std::chrono::milliseconds handshake_timeout{10000};
    std::chrono::milliseconds max_idle{std::chrono::minutes(30)};
    int max_health_watches = 64;
    // Lease calls waiting for work; a Lease beyond either cap does not wait.
    int max_lease_polls = 256;
    int max_lease_polls_per_session = 64;
    // FetchImage calls at once; of them, those of a render still in memory, which are
    // encoded in memory.
    int max_fetches = 16;
    int max_fetches_from_memory = 2;
    // Watch streams at once.
    int max_watches = 32;
    // Of the FetchImage and Watch places, one peer address (its host, without the port)
    // holds at most these, so that a client reconnecting as fast as it is cut leaves a
    // quarter to other addresses, as the HTTP image routes and threads do.
    int max_fetches_per_peer = 12;
    int max_watches_per_peer = 24;
    // Of the FetchImage places of a running render, one address holds at most this many,
    // so that one is always there for others.
    int max_fetches_from_memory_per_peer = 1;
    // Tests only: called by a FetchImage of a running render once it holds its place,
    // before it copies anything; a test that blocks in it holds places without timing.
    std::function<void()> running_fetch_admitted;
    // A FetchImage or Watch stream must be taken at stream_min_rate at least after a
    // grace, as the HTTP image routes are: each write within stream_grace + its bytes /
    // stream_min_rate, and a FetchImage whole within stream_grace + its size /
    // stream_min_rate. Else the call is cancelled (StreamWatchdog), freeing its thread
    // and place: gRPC's Write waits for as long as the client reads nothing.
    std::chrono::milliseconds stream_grace{30000};
    size_t stream_min_rate = 64 * 1024;  // bytes a second
    // A Watch stream ends (OK) after this long, so that one whose client reads nothing
    // (whose few updates the buffers would take for hours) gives its place back; the
    // client (`aliquot watch`) opens another.
    std::chrono::milliseconds watch_life{std::chrono::minutes(15)};
    // Every `watchdog_period` a new connection to the server's own port checks that it
    // is accepted (accepts_connections); after `watchdog_failures` failures in a row the
    // server is started again, and if it cannot be, the process exits
    // (ListenerWatchdog). 0 failures: no watchdog.
    std::chrono::milliseconds watchdog_period{2000};
    int watchdog_failures = 3;
};

struct GrpcOptions {
    // Where the worker service's Lease and merge latencies go; none when null.
    FarmMetrics* metrics = nullptr;
    // Serve grpc.reflection.v1alpha.ServerReflection (grpcurl and grpc_cli list and
    // describe the services through it). Off by default: each reflection stream holds a
    // server thread while open, and it needs no token.
    bool reflection = false;
};

class GrpcServer {
public:
    // Listens on `address` (host:port); throws std::runtime_error if it cannot, and
    // std::invalid_argument for unusable security settings. Health answers SERVING for
    // "" (the whole server), aliquot.v1.ClientService and aliquot.v1.WorkerService.
    // First raises the process's open-file limit as far as it goes (open_file_limit.h).
    GrpcServer(Coordinator& coordinator, const std::string& address,
               GrpcSecurity security, GrpcOptions options = {}, GrpcLimits limits = {});
    ~GrpcServer();
    int port() const { return port_.load(); }
    // Health answers NOT_SERVING from now on, for every service, while calls are still
    // served: the first step of shutting down, so that probes and load balancers turn
    // away before the port closes. Idempotent.
    void stop_serving();
    // stop_serving(), then stops: calls still running get 2 s to end. Idempotent.
    void shutdown();
    // How many times the watchdog started the listener again (for tests).
    int restarts();

private:
    struct Services;
    // Builds and starts a server on `address` into server_; under mutex_.
    void listen(const std::string& address);
    // The watchdog's probe: whether a new connection is accepted.
    bool reachable();
    // The watchdog found the listener deaf: stop the server, start another on the same
    // port, or exit.
    void listen_again();

    Coordinator& coordinator_;
    const GrpcSecurity security_;
    const GrpcOptions options_;
    const GrpcLimits limits_;
    std::mutex mutex_;  // guards what follows (the watchdog's thread and the caller's)
    std::unique_ptr<Services> services_;
    std::unique_ptr<grpc::Server> server_;
    // Written again by the listener watchdog's thread (listen_again), read by any.
    std::atomic<int> port_{0};
    std::string host_;  // as given, for listening again on the same port
    bool serving_ = true, stopped_ = false;
    int restarts_ = 0;
    std::unique_ptr<ListenerWatchdog> watchdog_;
};

}  // namespace aliquot
