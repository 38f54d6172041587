#include "access.h"

#include <stdexcept>

#include "secret.h"
#include "token_file.h"

namespace aliquot {

std::string_view to_string(Role role) {
    return role == Role::Client ? "client" : "worker";
}

void check_tokens(const Tokens& tokens) {
    try {
        check_token(tokens.client, "the client token");
        check_token(tokens.worker, "the worker token");
    } catch (const TokenError& e) {
        throw std::invalid_argument(e.what());
    }
    if (tokens.client == tokens.worker)
        throw std::invalid_argument(
            "the client and worker tokens are the same: a token names its role, so they "
            "must differ");
}

std::string_view bearer_token(std::string_view authorization) {
    constexpr std::string_view kScheme = "bearer ";
    if (authorization.size() <= kScheme.size()) return {};
    for (size_t i = 0; i < kScheme.size(); ++i) {
        char c = authorization[i];
        if (c >= 'A' && c <= 'Z') c = char(c - 'A' + 'a');
        if (c != kScheme[i]) return {};
    }
    std::string_view token = authorization.substr(kScheme.size());
    while (!token.empty() && token.front() == ' ') token.remove_prefix(1);
    while (!token.empty() && token.back() == ' ') token.remove_suffix(1);
    return token;
}

Access check_access(const Tokens& tokens, std::string_view presented, Role needed) {
    if (presented.empty()) return Access::Unauthenticated;
    // Both comparisons always run, so the time taken does not say which role matched.
    const bool client = constant_time_equal(presented, tokens.client);
    const bool worker = constant_time_equal(presented, tokens.worker);
    const bool right = needed == Role::Client ? client : worker;
    const bool other = needed == Role::Client ? worker : client;
    if (right) return Access::Granted;
    return other ? Access::Forbidden : Access::Unauthenticated;
}

std::string access_message(Access access, Role needed) {
    const std::string role(to_string(needed));
    switch (access) {
        case Access::Granted:
            return "";
        case Access::Forbidden:
            return "this call needs the " + role +
                   " token; the token sent is the other role's";
        case Access::Unauthenticated:
            break;
    }
    return "this call needs the " + role +
           " token (Authorization: Bearer; see --token-file or ALIQUOT_TOKEN)";
}

}  // namespace aliquot
