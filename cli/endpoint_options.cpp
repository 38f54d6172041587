#include "endpoint_options.h"

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "commands.h"
#include "token_file.h"

namespace aliquot::cli {

namespace {

// Whether `path` exists now or within `wait`: `aliquot coordinator & aliquot worker`
// started together in one directory race to it, and the coordinator writes its tokens a
// moment after it starts.
bool appears_within(const std::filesystem::path& path, std::chrono::milliseconds wait) {
    const auto until = std::chrono::steady_clock::now() + wait;
    while (!std::filesystem::exists(path)) {
        if (std::chrono::steady_clock::now() >= until) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return true;
}

}  // namespace

void EndpointOptions::add_to(CLI::App& cmd, Role role) {
    const std::string name(to_string(role));
    cmd.add_option("--coordinator", address, "coordinator address host:port")
        ->capture_default_str();
    cmd.add_option("--token-file", token_file,
                   "file holding the coordinator's " + name +
                       " token (default: $ALIQUOT_TOKEN, else aliquot-data/" + name +
                       ".token here, where a coordinator started in this directory "
                       "writes it)");
    cmd.add_option("--tls-ca", tls_ca,
                   "PEM file of the CA that signed the coordinator's certificate: "
                   "connect over TLS (docs/SECURITY.md)");
}

CoordinatorEndpoint EndpointOptions::resolve(Role role) const {
    CoordinatorEndpoint endpoint;
    endpoint.address = address;
    const std::string name(to_string(role));
    // The default token is the one a coordinator with the default --data writes in the
    // current directory: `aliquot coordinator` and `aliquot submit` side by side work
    // without flags, and nothing is read from anywhere else.
    const std::filesystem::path local =
        std::filesystem::path("aliquot-data") / (name + ".token");
    try {
        if (!token_file.empty()) {
            endpoint.token = read_token_file(token_file);
        } else if (const char* env = std::getenv("ALIQUOT_TOKEN"); env && *env) {
            endpoint.token = env;
            check_token(endpoint.token, "ALIQUOT_TOKEN");
        } else if (appears_within(local, std::chrono::seconds(5))) {
            endpoint.token = read_token_file(local);
        } else {
            throw CommandError("no " + name +
                               " token: pass --token-file PATH (the coordinator writes "
                               "DATA/" +
                               name + ".token at its first start) or set ALIQUOT_TOKEN");
        }
    } catch (const TokenError& e) {
        throw CommandError(e.what());
    }
    if (!tls_ca.empty()) {
        std::ifstream in(tls_ca, std::ios::binary);
        std::ostringstream pem;
        pem << in.rdbuf();
        if (!in || pem.str().empty())
            throw CommandError("--tls-ca: cannot read " + tls_ca);
        endpoint.tls_ca_pem = pem.str();
    }
    return endpoint;
}

}  // namespace aliquot::cli
