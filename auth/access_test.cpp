#include "access.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace aliquot {
namespace {

const Tokens kTokens{"client-secret-0123456789", "worker-secret-0123456789"};

TEST(BearerToken, ReadsTheTokenOfTheBearerSchemeOnly) {
    EXPECT_EQ(bearer_token("Bearer abc"), "abc");
    EXPECT_EQ(bearer_token("bearer  abc "), "abc");
    EXPECT_EQ(bearer_token("BEARER abc"), "abc");
    EXPECT_EQ(bearer_token("Basic YWxhZGRpbjpvcGVuc2VzYW1l"), "");
    EXPECT_EQ(bearer_token("Bearer"), "");
    EXPECT_EQ(bearer_token("Bearer "), "");
    EXPECT_EQ(bearer_token(""), "");
    EXPECT_EQ(bearer_token("Bearerabc"), "");
}

TEST(CheckAccess, EachRoleOnlyWithItsOwnToken) {
    EXPECT_EQ(check_access(kTokens, kTokens.client, Role::Client), Access::Granted);
    EXPECT_EQ(check_access(kTokens, kTokens.worker, Role::Worker), Access::Granted);
    EXPECT_EQ(check_access(kTokens, kTokens.worker, Role::Client), Access::Forbidden);
    EXPECT_EQ(check_access(kTokens, kTokens.client, Role::Worker), Access::Forbidden);
}

TEST(CheckAccess, NoTokenOrAWrongOneIsUnauthenticated) {
    EXPECT_EQ(check_access(kTokens, "", Role::Client), Access::Unauthenticated);
    EXPECT_EQ(check_access(kTokens, "client-secret-012345678", Role::Client),
              Access::Unauthenticated);
    EXPECT_EQ(check_access(kTokens, "client-secret-01234567890", Role::Client),
              Access::Unauthenticated);
    EXPECT_EQ(check_access(kTokens, "Client-secret-0123456789", Role::Client),
              Access::Unauthenticated);
}

TEST(CheckAccess, TheMessageNamesTheRoleNeverTheToken) {
    const std::string m = access_message(Access::Forbidden, Role::Worker);
    EXPECT_NE(m.find("worker token"), std::string::npos);
    EXPECT_EQ(m.find(kTokens.worker), std::string::npos);
    EXPECT_EQ(access_message(Access::Granted, Role::Client), "");
}

TEST(CheckTokens, BothUsableAndDifferentOrRefused) {
    EXPECT_NO_THROW(check_tokens(kTokens));
    EXPECT_THROW(check_tokens({}), std::invalid_argument);
    EXPECT_THROW(check_tokens({kTokens.client, ""}), std::invalid_argument);
    EXPECT_THROW(check_tokens({kTokens.client, kTokens.client}), std::invalid_argument);
    EXPECT_THROW(check_tokens({"short", kTokens.worker}), std::invalid_argument);
    // What a cookie or an HTTP header would split, quote or percent-decode.
    for (const char* odd : {"client;token-0123456789", "client,token-0123456789",
                            "client\"token-0123456789", "client\\token-0123456789",
                            "client%41token-0123456789", "client token-0123456789",
                            "client\ttoken-0123456789"})
        EXPECT_THROW(check_tokens({odd, kTokens.worker}), std::invalid_argument) << odd;
}

}  // namespace
}  // namespace aliquot
