// Who may use the HTTP server: the checks every request passes before any route (its
// body's encoding, cross-site requests, the client token or a session), and the
// dashboard's sign-in (docs/SECURITY.md); a group of HttpServer's routes
// (http_server_impl.h).
#include "http_server_impl.h"

#include <algorithm>
#include <cctype>
#include <string_view>

#include "http_session.h"

namespace aliquot {

namespace {

bool iequals(std::string_view a, std::string_view b) {
    return a.size() == b.size() &&
           std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower((unsigned char)x) == std::tolower((unsigned char)y);
           });
}

}  // namespace

// Before any route, file or body: refuses requests another site's page could make
// (docs/SECURITY.md, "Cross-site requests"). A refused request's body is never read,
// so its connection is closed.
httplib::Server::HandlerResponse HttpServer::Impl::refuse(httplib::Response& res,
                                                          int status,
                                                          const std::string& message) {
    res.set_header("Connection", "close");
    send_error(res, status, message);
    return httplib::Server::HandlerResponse::Handled;
}

httplib::Server::HandlerResponse HttpServer::Impl::cross_site_check(
    const httplib::Request& req, httplib::Response& res) {
    // Probes (Docker, Kubernetes) name the container or pod by its IP or not at all;
    // /healthz answers {"ok": true} only, which tells a rebinding page nothing.
    if (req.path == "/healthz") return httplib::Server::HandlerResponse::Unhandled;
    const std::string host = req.get_header_value("Host");
    if (!hosts->allows(host))
        return refuse(res, 403,
                      "Host header \"" + host.substr(0, 100) +
                          "\" is not this server's (allowed: " + hosts->describe() +
                          "; add names with --allow-host)");
    const bool mutating =
        req.method != "GET" && req.method != "HEAD" && req.method != "OPTIONS";
    if (mutating && req.has_header("Origin") &&
        !http_api::origin_matches_host(req.get_header_value("Origin"), host, https))
        return refuse(res, 403,
                      "cross-origin request refused: Origin \"" +
                          req.get_header_value("Origin").substr(0, 100) + "\" is not " +
                          (https ? "https://" : "http://") + host);
    if (mutating && !http_api::is_json_content_type(req.get_header_value("Content-Type")))
        return refuse(
            res, 415,
            "a " + req.method + " request must have Content-Type: application/json");
    return httplib::Server::HandlerResponse::Unhandled;
}

// httplib inflates a gzip or brotli body before any handler sees it, and its size
// limit counts the compressed bytes: 1 MB of gzip became 1000 MiB, before the token
// was looked at. Nothing the API takes is sent compressed, so no compressed body is
// accepted, refused before it is read.
httplib::Server::HandlerResponse HttpServer::Impl::encoding_check(
    const httplib::Request& req, httplib::Response& res) {
    const auto [first, last] = req.headers.equal_range("Content-Encoding");
    for (auto it = first; it != last; ++it) {
        std::string_view coding = it->second;
        while (!coding.empty() && (coding.front() == ' ' || coding.front() == '\t'))
            coding.remove_prefix(1);
        while (!coding.empty() && (coding.back() == ' ' || coding.back() == '\t'))
            coding.remove_suffix(1);
        if (!iequals(coding, "identity"))
            return refuse(res, 415,
                          "a request body may not be compressed (Content-Encoding \"" +
                              it->second.substr(0, 40) + "\"); send it as it is");
    }
    return httplib::Server::HandlerResponse::Unhandled;
}

// The bearer token when the request sends one, else the session its cookie names.
// A cookie is only ever a session id: the client token in a cookie opens nothing.
Access HttpServer::Impl::presented_access(const httplib::Request& req) {
    const std::string authorization = req.get_header_value("Authorization");
    const std::string_view bearer = bearer_token(authorization);
    if (!bearer.empty()) return check_access(options.tokens, bearer, Role::Client);
    const std::string id =
        http_session::cookie_value(req.get_header_value("Cookie"), cookie_name);
    return !id.empty() && sessions.use(id) ? Access::Granted : Access::Unauthenticated;
}

// After the cross-site checks, so that a foreign page learns nothing more from a 401
// than from a 403. Only the client token (or a session it opened) opens the API.
httplib::Server::HandlerResponse HttpServer::Impl::token_check(
    const httplib::Request& req, httplib::Response& res) {
    const Access access = presented_access(req);
    if (access == Access::Granted) {
        HttpFront::trust_current_request();
        return httplib::Server::HandlerResponse::Unhandled;
    }
    if (http_session::needs_token(req.method, req.path)) {
        res.set_header("Connection", "close");  // its body is never read
        send_refusal(res, access);
        return httplib::Server::HandlerResponse::Handled;
    }
    // Without the token, only a body the front has read whole (a sign-in): such a
    // request never holds a thread while its body trickles in.
    if (req.has_header("Transfer-Encoding"))
        return refuse(res, 411,
                      "a request without the client token must send Content-Length");
    if (req.get_header_value<uint64_t>("Content-Length") > options.front.max_small_body)
        return refuse(res, 413,
                      "a request without the client token may send at most " +
                          std::to_string(options.front.max_small_body) + " bytes");
    return httplib::Server::HandlerResponse::Unhandled;
}

// 401 with WWW-Authenticate (no or a wrong token) or 403 (the worker's), as JSON.
void HttpServer::Impl::send_refusal(httplib::Response& res, Access access) {
    if (access == Access::Unauthenticated) res.set_header("WWW-Authenticate", "Bearer");
    send_error(res, access == Access::Forbidden ? 403 : 401,
               http_session::refusal_message(access));
}

// The dashboard's sign-in: the client token opens a session, whose random id the
// cookie carries (docs/API.md, "Authentication"). GET needs the token like every
// route; POST and DELETE do not.
void HttpServer::Impl::session_routes() {
    server.Get("/api/session", [](const httplib::Request&, httplib::Response& res) {
        send_json(res, {{"signed_in", true}});
    });
    server.Post(
        "/api/session", guarded([this](const httplib::Request& req, auto& res) {
            const std::string token = http_session::parse_sign_in_request(req.body);
            const Access access = check_access(options.tokens, token, Role::Client);
            if (access == Access::Granted) {
                res.set_header("Set-Cookie", http_session::sign_in_cookie(
                                                 cookie_name, sessions.open(), https));
                send_json(res, {{"ok", true}});
                return;
            }
            send_refusal(res, access);
        }));
    // Ends the session the cookie names, so that a copy of the cookie opens nothing
    // either; knowing the id is what signing out needs.
    server.Delete("/api/session", [this](const httplib::Request& req,
                                         httplib::Response& res) {
        const std::string id =
            http_session::cookie_value(req.get_header_value("Cookie"), cookie_name);
        if (!id.empty()) sessions.close(id);
        res.set_header("Set-Cookie", http_session::sign_out_cookie(cookie_name, https));
        send_json(res, {{"ok", true}});
    });
}

}  // namespace aliquot
