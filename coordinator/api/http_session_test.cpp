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

TEST(PresentedToken, TheBearerWinsOverTheCookie) {
    EXPECT_EQ(presented_token("Bearer abc", "aliquot_session=def"), "abc");
    EXPECT_EQ(presented_token("", "aliquot_session=def"), "def");
    EXPECT_EQ(presented_token("Basic abc", "aliquot_session=def"), "def");
    EXPECT_EQ(presented_token("", ""), "");
}

TEST(CookieToken, FindsOurCookieAmongOthers) {
    EXPECT_EQ(cookie_token("aliquot_session=abc"), "abc");
    EXPECT_EQ(cookie_token("theme=dark; aliquot_session=abc; lang=en"), "abc");
    EXPECT_EQ(cookie_token("theme=dark;aliquot_session=\"abc\""), "abc");
    EXPECT_EQ(cookie_token("aliquot_session=first; aliquot_session=second"), "first");
    EXPECT_EQ(cookie_token("xaliquot_session=abc"), "");
    EXPECT_EQ(cookie_token("aliquot_sessionx=abc"), "");
    EXPECT_EQ(cookie_token("theme=dark"), "");
    EXPECT_EQ(cookie_token(""), "");
    EXPECT_EQ(cookie_token("aliquot_session="), "");
}

TEST(SessionCookie, CarriesTheTokenWithItsAttributes) {
    EXPECT_EQ(sign_in_cookie("0123abcd", false),
              "aliquot_session=0123abcd; HttpOnly; SameSite=Strict; Path=/");
    EXPECT_EQ(sign_out_cookie(false),
              "aliquot_session=; Max-Age=0; HttpOnly; SameSite=Strict; Path=/");
    // Under TLS the browser must never send it over plain HTTP.
    EXPECT_EQ(sign_in_cookie("0123abcd", true),
              "aliquot_session=0123abcd; HttpOnly; SameSite=Strict; Path=/; Secure");
    EXPECT_EQ(sign_out_cookie(true),
              "aliquot_session=; Max-Age=0; HttpOnly; SameSite=Strict; Path=/; Secure");
}

// Every character a token may have (check_token: RFC 6750's b64token) survives the
// cookie unchanged; those that would not are refused for tokens (auth/access_test.cpp).
TEST(SessionCookie, CarriesEveryTokenCharacterAsItIs) {
    const std::string token =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-._~+/=";
    const std::string set = sign_in_cookie(token, false);
    EXPECT_EQ(cookie_token(set.substr(0, set.find("; "))), token);
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
