#include "http_session.h"

#include <nlohmann/json.hpp>

#include "http_api.h"
#include "json_field.h"

namespace aliquot::http_session {

namespace {

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
    return s;
}

}  // namespace

bool needs_token(std::string_view method, std::string_view path) {
    // Everything under /api, however it is spelled below it: a route added later is
    // guarded without anyone remembering to.
    // /metrics too: the farm's counts and rates are the client's to read (docs/API.md).
    if (path == "/metrics" || path.starts_with("/metrics/")) return true;
    if (path != "/api" && !path.starts_with("/api/")) return false;
    if (path == "/api/session") return method != "POST" && method != "DELETE";
    return true;
}

std::string cookie_name(int port, bool https) {
    return std::string(https ? "__Host-" : "") + "aliquot_session_" +
           std::to_string(port);
}

std::string cookie_value(std::string_view cookie_header, std::string_view name) {
    // "a=1; aliquot_session_8080=ID; b=2" (RFC 6265, 5.4); the first of ours counts.
    while (!cookie_header.empty()) {
        const size_t end = cookie_header.find(';');
        const std::string_view pair = trim(cookie_header.substr(0, end));
        const size_t eq = pair.find('=');
        if (eq != std::string_view::npos && trim(pair.substr(0, eq)) == name) {
            std::string_view value = trim(pair.substr(eq + 1));
            if (value.size() >= 2 && value.front() == '"' && value.back() == '"')
                value = value.substr(1, value.size() - 2);
            return std::string(value);
        }
        if (end == std::string_view::npos) break;
        cookie_header.remove_prefix(end + 1);
    }
    return {};
}

std::string cookie_attributes(bool https) {
    return std::string("HttpOnly; SameSite=Strict; Path=/") + (https ? "; Secure" : "");
}

std::string sign_in_cookie(std::string_view name, std::string_view id, bool https) {
    return std::string(name) + "=" + std::string(id) + "; " + cookie_attributes(https);
}

std::string sign_out_cookie(std::string_view name, bool https) {
    return std::string(name) + "=; Max-Age=0; " + cookie_attributes(https);
}

std::string parse_sign_in_request(const std::string& body) {
    try {
        const nlohmann::json doc = parse_json(body);
        const JsonField root(doc);
        root.expect_object("a sign-in is a JSON object: {\"token\": \"...\"}");
        root.allow_keys({"token"});
        return root.require("token").string("the client token, as a string");
    } catch (const JsonError& e) {
        // Not JSON at all: the parser's message would quote the body, which holds a
        // secret; say what is expected instead.
        if (!e.pointer())
            throw http_api::ApiError(400,
                                     "a sign-in is a JSON object: {\"token\": \"...\"}");
        throw http_api::ApiError(400, e.what());
    }
}

std::string refusal_message(Access access) {
    if (access == Access::Forbidden)
        return "the HTTP API needs the client token; the token sent is the worker's";
    return "the HTTP API needs the client token: send Authorization: Bearer TOKEN, or "
           "sign "
           "in with POST /api/session (the coordinator keeps it in DATA/client.token)";
}

}  // namespace aliquot::http_session
