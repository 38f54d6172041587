// Who may call what: two roles with separate bearer tokens. A client submits, cancels and
// reads; a worker registers, leases, completes, renews, abandons and fetches scenes. Both
// the gRPC services and the HTTP API ask check_access before anything else.
#pragma once

#include <string>
#include <string_view>

namespace aliquot {

enum class Role { Client, Worker };
std::string_view to_string(Role role);

// The coordinator's two secrets. They must differ: a token names its role.
struct Tokens {
    std::string client;
    std::string worker;
};

// Throws std::invalid_argument unless both tokens are usable (check_token) and differ:
// what every server that admits callers by them checks first.
void check_tokens(const Tokens& tokens);

enum class Access {
    Granted,
    Unauthenticated,  // no token, or one that is neither role's: gRPC UNAUTHENTICATED,
                      // 401
    Forbidden,        // the other role's token: gRPC PERMISSION_DENIED, 403
};

// The token of an `Authorization: Bearer TOKEN` value; empty when the header is absent or
// uses another scheme. The scheme is case-insensitive (RFC 7235).
std::string_view bearer_token(std::string_view authorization);

// Compares `presented` with both tokens in constant time.
Access check_access(const Tokens& tokens, std::string_view presented, Role needed);

// What the refused caller is told: which token is needed, never what it is.
std::string access_message(Access access, Role needed);

}  // namespace aliquot
