// --coordinator, --token-file and --tls-ca: how a client command or a worker reaches a
// coordinator, read the same way by each.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "access.h"
#include "channel.h"

namespace aliquot::cli {

struct EndpointOptions {
    std::string address = "127.0.0.1:7070";
    std::string token_file;  // empty: ALIQUOT_TOKEN, then aliquot-data/ROLE.token
    std::string tls_ca;      // empty: plaintext

    // Adds the three options to `cmd`; `role` says which token the help asks for.
    void add_to(CLI::App& cmd, Role role);
    // The endpoint with its token and CA read; throws CommandError when there is no
    // usable token or the CA cannot be read.
    CoordinatorEndpoint resolve(Role role) const;
};

}  // namespace aliquot::cli
