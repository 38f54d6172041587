// The coordinator's HTTP face: the JSON API of docs/API.md, live updates as server-sent
// events, study reports, and the built dashboard's static files. Thin over Coordinator,
// like GrpcServer.
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "access.h"
#include "browser_sessions.h"
#include "coordinator.h"
#include "http_front.h"
#include "metrics.h"

namespace aliquot {

struct HttpOptions {
    // Every /api/ route needs the client token (docs/API.md, "Authentication"); the
    // worker token is refused with 403. Both must be set and differ.
    Tokens tokens;
    // The built dashboard (web/dist); when it has no index.html, / explains how to build
    // it and the API works alone.
    std::filesystem::path web_dir;
    // Where `aliquot study` reports live, each with the label the API names it by
    // ("data", "docs"): every subdirectory with a top-level .md report is one study.
    std::vector<std::pair<std::string, std::filesystem::path>> study_dirs;
    // The shortest gap between two live updates: the browser never gets more than a few
    // per second however fast results arrive.
    std::chrono::milliseconds event_interval{250};
    // Listed renders per request at most (GET /api/renders?limit=).
    size_t max_list = 1000;
    // Event streams open at once at most; one more is refused with 503 and Retry-After.
    // Each open stream holds one of the server's threads (front.threads, 32), so 8 always
    // stay free for everything else (the API, /healthz, the dashboard's files).
    size_t max_event_streams = 16;
    // Of them, one peer address holds at most this many, so that 4 are always there for
    // other addresses, as 8 of the threads are (FrontLimits::max_threads_per_peer).
    size_t max_event_streams_per_peer = 12;
    // An event stream ends after this long, so that one whose client reads nothing
    // (whose events the sockets' buffers would take for hours) gives its place and
    // thread back; the dashboard reconnects at once and fetches afresh.
    std::chrono::milliseconds event_stream_life{std::chrono::minutes(15)};
    // Requests that make or send an image at once at most (preview.png, thumbnail.png
    // when made anew, maps, image.exr, together); one more is refused with 503 and
    // Retry-After. Each may hold a copy of a render's image and its encoding; a browser
    // opens at most 6 connections to a host, so one dashboard is never refused.
    size_t max_image_requests = 8;
    // Of them, one peer address holds at most this many: a holder of the token who
    // reconnects as fast as it is cut keeps 2 places free for other addresses, and a
    // dashboard (6 connections at most) still never meets its share.
    size_t max_image_requests_per_peer = 6;
    // Tests only: called by an image route once it holds its place, before it makes
    // anything; a test that blocks in it holds places without timing.
    std::function<void()> image_admitted;
    // How often an idle event stream looks whether its client has left: a departed
    // client's thread is free again within about this long.
    std::chrono::milliseconds client_check_interval{250};
    // Host names besides the listen address that requests may name in their Host header
    // (a compose or Kubernetes service name): "NAME" on any port or "NAME:PORT". Every
    // other Host is refused with 403 (docs/SECURITY.md, "Cross-site requests").
    std::vector<std::string> allowed_hosts;
    // PEM files of the certificate (chain) and its private key: serve HTTPS, not HTTP.
    // Both or neither; the coordinator passes its --tls-cert and --tls-key, the same pair
    // as gRPC's.
    std::filesystem::path tls_cert, tls_key;
    // Served as GET /metrics (Prometheus' text format, the client token required);
    // without it /metrics is 404.
    FarmMetrics* metrics = nullptr;
    // What a connection may send and how long it may take, and the server's threads
    // (docs/SECURITY.md, "HTTP connections").
    FrontLimits front;
    // The dashboard's sessions: how many, and when they end.
    SessionLimits sessions;
};

class HttpServer {
public:
    // Listens on `address` (host:port; port 0 picks a free one); throws
    // std::runtime_error if it cannot, or cannot load the TLS certificate and key;
    // std::invalid_argument for options it refuses (no tokens, the same token for both
    // roles, a client token a cookie cannot carry).
    HttpServer(Coordinator& coordinator, const std::string& address,
               HttpOptions options = {});
    ~HttpServer();
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;

    int port() const;
    // Ends open event streams and stops serving; idempotent.
    void shutdown();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace aliquot
