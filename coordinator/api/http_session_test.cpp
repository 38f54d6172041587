#include "http_session.h"

#include <gtest/gtest.h>

#include "http_api.h"

namespace aliquot::http_session {
namespace {

TEST(NeedsToken, MetricsNeedTheClientToken) {
    EXPECT_TRUE(needs_token("GET", "/metrics"));
    EXPECT_TRUE(needs_token("GET", "/metrics/"));
    EXPECT_FALSE(needs_token("GET", "/metricsfoo"));
}

TEST(NeedsToken, EveryApiRouteButSigningInAndOut) {
    EXPECT_TRUE(needs_token("GET", "/api/renders"));
    EXPECT_TRUE(needs_token("POST", "/api/renders"));
    EXPECT_TRUE(needs_token("GET", "/api/events"));
    EXPECT_TRUE(needs_token("GET", "/api/studies/data/x/report.md"));
    EXPECT_TRUE(needs_token("GET", "/api/no-such-route"));
    EXPECT_TRUE(needs_token("GET", "/api"));
    EXPECT_TRUE(needs_token("GET", "/api/session"));
    EXPECT_FALSE(needs_token("POST", "/api/session"));
    EXPECT_FALSE(needs_token("DELETE", "/api/session"));
    EXPECT_TRUE(needs_token("POST", "/api/session/x"));
    EXPECT_FALSE(needs_token("GET", "/healthz"));
    EXPECT_FALSE(needs_token("GET", "/"));
    EXPECT_FALSE(needs_token("GET", "/assets/index-1234.js"));
    EXPECT_FALSE(needs_token("GET", "/apiary.png"));
}

TEST(CookieValue, FindsOurCookieAmongOthers) {
    const std::string name = "aliquot_session_8080";
    EXPECT_EQ(cookie_value("aliquot_session_8080=abc", name), "abc");
    EXPECT_EQ(cookie_value("theme=dark; aliquot_session_8080=abc; lang=en", name), "abc");
    EXPECT_EQ(cookie_value("theme=dark;aliquot_session_8080=\"abc\"", name), "abc");
    EXPECT_EQ(
        cookie_value("aliquot_session_8080=first; aliquot_session_8080=second", name),
        "first");
    EXPECT_EQ(cookie_value("xaliquot_session_8080=abc", name), "");
    EXPECT_EQ(cookie_value("aliquot_session_80800=abc", name), "");
    EXPECT_EQ(cookie_value("theme=dark", name), "");
    EXPECT_EQ(cookie_value("", name), "");
    EXPECT_EQ(cookie_value("aliquot_session_8080=", name), "");
}

// A server on another port of the same host gets the cookie too (browsers do not keep
// cookies apart by port) but never reads it as its own.
TEST(CookieName, NamesThePort) {
    EXPECT_EQ(cookie_name(8080, false), "aliquot_session_8080");
    EXPECT_EQ(cookie_name(8443, true), "__Host-aliquot_session_8443");
    EXPECT_EQ(cookie_value("aliquot_session_8080=abc", cookie_name(8081, false)), "");
    EXPECT_EQ(cookie_value("aliquot_session=abc", cookie_name(8080, false)), "");
}

TEST(SessionCookie, CarriesTheSessionIdWithItsAttributes) {
    EXPECT_EQ(sign_in_cookie("aliquot_session_8080", "0123abcd", false),
              "aliquot_session_8080=0123abcd; HttpOnly; SameSite=Strict; Path=/");
    EXPECT_EQ(sign_out_cookie("aliquot_session_8080", false),
              "aliquot_session_8080=; Max-Age=0; HttpOnly; SameSite=Strict; Path=/");
    // Under TLS the browser must never send it over plain HTTP (and __Host- needs it).
    EXPECT_EQ(sign_in_cookie("__Host-aliquot_session_8443", "0123abcd", true),
              "__Host-aliquot_session_8443=0123abcd; HttpOnly; SameSite=Strict; Path=/; "
              "Secure");
    EXPECT_EQ(sign_out_cookie("__Host-aliquot_session_8443", true),
              "__Host-aliquot_session_8443=; Max-Age=0; HttpOnly; SameSite=Strict; "
              "Path=/; Secure");
}

TEST(SignInRequest, ReadsTheTokenAndRefusesAnythingElse) {
    EXPECT_EQ(parse_sign_in_request(R"({"token":"abc"})"), "abc");
    for (const char* body :
         {"", "abc", "[]", R"({"token":1})", "{}", R"({"token":"abc","remember":true})",
          R"({"token":"abc","token":"def"})"}) {
        try {
            parse_sign_in_request(body);
            ADD_FAILURE() << body;
        } catch (const http_api::ApiError& e) {
            EXPECT_EQ(e.status(), 400) << body;
        }
    }
}

TEST(SignInRequest, ABodyThatIsNotJsonIsNotQuotedBack) {
    try {
        parse_sign_in_request(R"({"token": s3cr3t-t0ken-value})");
        ADD_FAILURE() << "accepted";
    } catch (const http_api::ApiError& e) {
        EXPECT_EQ(std::string(e.what()).find("s3cr3t"), std::string::npos) << e.what();
    }
}

TEST(RefusalMessage, SaysWhereTheTokenIs) {
    EXPECT_NE(refusal_message(Access::Unauthenticated).find("DATA/client.token"),
              std::string::npos);
    EXPECT_NE(refusal_message(Access::Forbidden).find("worker's"), std::string::npos);
}

}  // namespace
}  // namespace aliquot::http_session
