// HttpServer (http_server.h): starting and stopping its listener, front and broadcaster,
// and the order its routes are set in; the routes themselves are in the files that
// http_server_impl.h names.
#include "http_server.h"

#include <algorithm>
#include <stdexcept>

#include "http_server_impl.h"
#include "http_session.h"

namespace aliquot {

// How many of the server's threads (FrontLimits::threads) event streams may never take.
constexpr size_t kFreeThreads = 8;

HttpServer::Impl::Impl(Coordinator& c, HttpOptions o)
    : coordinator(c),
      options(std::move(o)),
      made(make_server(options)),
      server(*made.server),
      https(!options.tls_cert.empty()),
      sessions(options.sessions) {}

void HttpServer::Impl::routes() {
    server.set_pre_routing_handler(
        [this](const httplib::Request& req, httplib::Response& res) {
            // httplib answers several ranges with a multipart body it builds in memory,
            // overlapping ones too: 2,700 times "0-" (an 8 KB header, no token) made a
            // 293 MB answer of a 108 KB dashboard file. One range (a resumed download)
            // is served; for more, the whole, as HTTP allows. httplib parsed them into
            // its own Request, which it hands every handler as const only.
            if (req.ranges.size() > 1) {
                auto& whole = const_cast<httplib::Request&>(req);
                whole.ranges.clear();
                whole.headers.erase("Range");
            }
            for (auto check :
                 {&Impl::encoding_check, &Impl::cross_site_check, &Impl::token_check})
                if ((this->*check)(req, res) == httplib::Server::HandlerResponse::Handled)
                    return httplib::Server::HandlerResponse::Handled;
            return httplib::Server::HandlerResponse::Unhandled;
        });
    // A refusal's body was never read: what follows it on the connection is not a
    // request, so the connection ends with the response (httplib would read on).
    server.set_post_routing_handler([](const httplib::Request&, httplib::Response& res) {
        if (res.get_header_value("Connection") == "close")
            HttpFront::close_after_current_response();
    });
    render_routes();
    session_routes();
    image_routes();
    farm_routes();
    event_routes();
    study_routes();
    error_routes();
    dashboard_route();
}

void HttpServer::Impl::error_routes() {
    // Whatever else went wrong (no such route, a body too large, a request httplib
    // could not parse) still answers JSON with a message.
    server.set_error_handler(httplib::Server::HandlerWithResponse(
        [](const httplib::Request& req, httplib::Response& res) {
            if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
            std::string message = "no such endpoint: " + req.method + " " + req.path;
            if (res.status == 413)
                message = "request body too large";
            else if (res.status == 400)
                message = "malformed HTTP request";
            else if (res.status != 404)
                message = "request refused (HTTP " + std::to_string(res.status) + ")";
            send_error(res, res.status, message);
            return httplib::Server::HandlerResponse::Handled;
        }));
    server.set_exception_handler(
        [](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
            send_error(res, 500, "internal error");
        });
}

void HttpServer::Impl::start(const std::string& address) {
    check_tokens(options.tokens);
    const size_t colon = address.rfind(':');
    if (colon == std::string::npos)
        throw std::runtime_error("http: address must be host:port, got \"" + address +
                                 "\"");
    std::string host = address.substr(0, colon);
    if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    if (host.empty()) host = "0.0.0.0";
    int wanted = -1;
    try {
        size_t used = 0;
        wanted = std::stoi(address.substr(colon + 1), &used);
        if (used != address.size() - colon - 1) wanted = -1;
    } catch (const std::exception&) {
    }
    if (wanted < 0 || wanted > 65535)
        throw std::runtime_error("http: bad port in \"" + address + "\"");

    // Event streams hold a thread each and browsers keep a few idle connections open;
    // at most max_event_streams of the threads go to streams.
    const size_t threads = options.front.threads;
    if (threads < kFreeThreads || options.max_event_streams + kFreeThreads > threads)
        throw std::invalid_argument(
            "http: at most " + std::to_string(threads - std::min(threads, kFreeThreads)) +
            " event streams, so that the server keeps threads for other requests");
    server.new_task_queue = [] { return new HandToFront; };
    server.set_payload_max_length(1 << 20);
    // What the Keep-Alive header tells clients; the front enforces both.
    server.set_keep_alive_max_count(options.front.requests_per_connection);
    server.set_keep_alive_timeout(std::max<time_t>(
        1,
        std::chrono::duration_cast<std::chrono::seconds>(options.front.request_deadline)
            .count()));
    http_api::HostPolicy(host, wanted,
                         options.allowed_hosts);  // throws on a bad entry
    routes();
    if (wanted == 0) {
        port = server.bind_to_any_port(host);
        if (port <= 0) throw std::runtime_error("http: cannot listen on " + address);
    } else {
        if (!server.bind_to_port(host, wanted))
            throw std::runtime_error("http: cannot listen on " + address);
        port = wanted;
    }
    made.requests->deepen_backlog();
    hosts.emplace(host, port, options.allowed_hosts);
    cookie_name = http_session::cookie_name(port, https);
    front = std::make_unique<HttpFront>(
        options.front, made.tls, [this](FrontConnection& c, bool close, bool& closed) {
            return made.requests->serve(c, close, closed);
        });
    made.requests->front = front.get();
    snapshot(false);  // later updates say what changed since now
    seen_storage_warning = coordinator.storage_warning();
    listener = std::thread([this] { server.listen_after_bind(); });
    // httplib's stop() does nothing until its listener has begun (is_running): a
    // server stopped at once would leave that thread in accept() for ever, and stop()
    // waiting for it. Bounded, should the listener end at once.
    for (int i = 0; i < 5000 && !server.is_running(); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    broadcaster = std::thread([this] { broadcast(); });
}

void HttpServer::Impl::stop() {
    std::call_once(stopped, [this] {
        hub.stop();
        server.stop();
        if (listener.joinable()) listener.join();
        if (front) front->stop();
        if (broadcaster.joinable()) broadcaster.join();
    });
}

HttpServer::HttpServer(Coordinator& coordinator, const std::string& address,
                       HttpOptions options)
    : impl_(std::make_unique<Impl>(coordinator, std::move(options))) {
    impl_->start(address);
}

HttpServer::~HttpServer() { shutdown(); }

int HttpServer::port() const { return impl_->port; }

void HttpServer::shutdown() { impl_->stop(); }

}  // namespace aliquot
