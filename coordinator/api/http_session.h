// Who may call the HTTP API: every /api/ route needs the client token, sent as
// `Authorization: Bearer TOKEN`, or, from the dashboard, a session cookie that signing in
// with the token sets. The cookie holds a session id of its own (BrowserSessions), never
// the token: it opens this server's HTTP API only and signing out ends it.
#pragma once

#include <string>
#include <string_view>

#include "access.h"

namespace aliquot::http_session {

// The session cookie's name, with this server's port in it: browsers send a host's
// cookies to every port of it, so a coordinator on another port of the same host receives
// this cookie but never takes it for its own. Under TLS with the `__Host-` prefix, which
// browsers accept only with Secure, Path=/ and no Domain: no other host can set it.
std::string cookie_name(int port, bool https);

// Whether a request needs the client token: every /api/ route and /metrics. /healthz and
// the dashboard's files (anything else) hold no data and must load for the page to show
// its sign-in view; signing in and out (POST and DELETE /api/session) are how a browser
// gets and drops the token.
bool needs_token(std::string_view method, std::string_view path);

// The value of the cookie `name` in a Cookie header (the first of that name); empty when
// it has none.
std::string cookie_value(std::string_view cookie_header, std::string_view name);

// The attributes every session cookie carries, set and cleared alike: the one place they
// are decided. HttpOnly keeps the token from the page's scripts; SameSite=Strict keeps
// the browser from sending it with any request another site starts. No Max-Age: the
// browser drops it when it closes, the server's expiry (SessionLimits) bounds it anyway.
// Under TLS (`https`) also Secure: the browser never sends it over plain HTTP.
std::string cookie_attributes(bool https);
// The Set-Cookie value that signs a browser in with session `id` (hex digits).
std::string sign_in_cookie(std::string_view name, std::string_view id, bool https);
// The Set-Cookie value that signs it out: the same cookie, expired.
std::string sign_out_cookie(std::string_view name, bool https);

// The token in the body of POST /api/session, {"token": "..."}. Throws
// http_api::ApiError(400) naming what is wrong, never echoing the body.
std::string parse_sign_in_request(const std::string& body);

// What a refused request is told (401 or 403): which token the API wants and where an
// operator finds it, never what was sent.
std::string refusal_message(Access access);

}  // namespace aliquot::http_session
