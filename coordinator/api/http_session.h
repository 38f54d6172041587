// Who may call the HTTP API: every /api/ route needs the client token, sent as
// `Authorization: Bearer TOKEN` or, from the dashboard, as the session cookie that
// signing in sets. The cookie carries the client token itself, so the server keeps no
// sessions: none to grow or lose at a restart, and rotating the token signs every browser
// out.
#pragma once

#include <string>
#include <string_view>

#include "access.h"

namespace aliquot::http_session {

inline constexpr std::string_view kCookieName = "aliquot_session";

// Whether a request needs the client token: every /api/ route and /metrics. /healthz and
// the dashboard's files (anything else) hold no data and must load for the page to show
// its sign-in view; signing in and out (POST and DELETE /api/session) are how a browser
// gets and drops the token.
bool needs_token(std::string_view method, std::string_view path);

// The token a request presents: its bearer token when it sends one, else the token in its
// session cookie; empty when it has neither.
std::string presented_token(std::string_view authorization,
                            std::string_view cookie_header);

// The token in a Cookie header's session cookie; empty when it has none.
std::string cookie_token(std::string_view cookie_header);

// The attributes every session cookie carries, set and cleared alike: the one place they
// are decided. HttpOnly keeps the token from the page's scripts; SameSite=Strict keeps
// the browser from sending it with any request another site starts.
// Under TLS (`https`) also Secure: the browser never sends it over plain HTTP.
std::string cookie_attributes(bool https);
// The Set-Cookie value that signs a browser in with `token` (check_tokens made sure a
// cookie carries it as it is).
std::string sign_in_cookie(std::string_view token, bool https);
// The Set-Cookie value that signs it out: the same cookie, expired.
std::string sign_out_cookie(bool https);

// The token in the body of POST /api/session, {"token": "..."}. Throws
// http_api::ApiError(400) naming what is wrong, never echoing the body.
std::string parse_sign_in_request(const std::string& body);

// What a refused request is told (401 or 403): which token the API wants and where an
// operator finds it, never what was sent.
std::string refusal_message(Access access);

}  // namespace aliquot::http_session
