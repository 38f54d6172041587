// --coordinator, --token-file, --tls-ca and --connect-timeout: how a client command or a
// worker reaches a coordinator, read the same way by each.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "access.h"
#include "channel.h"

namespace aliquot::cli {

// The PEM of a --tls-ca file, or CommandError naming it when it cannot be read.
std::string read_tls_ca(const std::string& path);

// The address when neither --coordinator nor ALIQUOT_COORDINATOR says.
inline constexpr const char* kDefaultCoordinator = "127.0.0.1:7070";

struct EndpointOptions {
    std::string address;     // empty: $ALIQUOT_COORDINATOR, then kDefaultCoordinator
    std::string token_file;  // empty: ALIQUOT_TOKEN, then aliquot-data/ROLE.token
    std::string tls_ca;      // empty: plaintext
    // One rule for a coordinator that is starting: its token file (the implicit one)
    // and its port are waited for, together, at most this long.
    double connect_timeout_seconds = 10;

    // Adds the four options to `cmd`; `role` says which token the help asks for.
    void add_to(CLI::App& cmd, Role role);
    // --coordinator, else $ALIQUOT_COORDINATOR, else kDefaultCoordinator.
    std::string effective_address() const;
    // The endpoint with its token and CA read, and what is left of the connect timeout
    // after waiting for the token file. Throws UsageError for a bad timeout and
    // CommandError when there is no usable token or the CA cannot be read.
    CoordinatorEndpoint resolve(Role role) const;
};

}  // namespace aliquot::cli
