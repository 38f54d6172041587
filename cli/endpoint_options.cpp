#include "endpoint_options.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "commands.h"
#include "port_probe.h"
#include "token_file.h"

namespace aliquot::cli {

std::string read_tls_ca(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream pem;
    pem << in.rdbuf();
    if (!in || pem.str().empty()) throw CommandError("--tls-ca: cannot read " + path);
    return pem.str();
}

namespace {

using Clock = std::chrono::steady_clock;

// Whether `path` exists now or appears before `until`: `aliquot coordinator & aliquot
// submit` started together in one directory race to it, and the coordinator writes its
// tokens a moment after it starts.
bool appears_by(const std::filesystem::path& path, Clock::time_point until) {
    while (!std::filesystem::exists(path)) {
        if (Clock::now() >= until) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return true;
}

// A day: longer is a typo, and the deadline arithmetic stays far from overflow.
constexpr double kMaxConnectTimeout = 86400;

}  // namespace

void EndpointOptions::add_to(CLI::App& cmd, Role role) {
    const std::string name(to_string(role));
    cmd.add_option("--coordinator", address,
                   std::string("coordinator address host:port (default: "
                               "$ALIQUOT_COORDINATOR, else ") +
                       kDefaultCoordinator + ")");
    cmd.add_option("--token-file", token_file,
                   "file holding the coordinator's " + name +
                       " token (default: $ALIQUOT_TOKEN, else aliquot-data/" + name +
                       ".token here, where a coordinator started in this directory "
                       "writes it)");
    cmd.add_option("--tls-ca", tls_ca,
                   "PEM file of the CA that signed the coordinator's certificate: "
                   "connect over TLS (docs/SECURITY.md)");
    cmd.add_option("--connect-timeout", connect_timeout_seconds,
                   "seconds to wait for a coordinator that is starting: for the "
                   "implicit token file to appear and for the port to answer (0: try "
                   "once)")
        ->capture_default_str();
}

std::string EndpointOptions::effective_address() const {
    if (!address.empty()) return address;
    if (const char* env = std::getenv("ALIQUOT_COORDINATOR"); env && *env) return env;
    return kDefaultCoordinator;
}

CoordinatorEndpoint EndpointOptions::resolve(Role role) const {
    if (!(connect_timeout_seconds >= 0 && connect_timeout_seconds <= kMaxConnectTimeout))
        throw UsageError("--connect-timeout: must be 0..86400 seconds");
    const auto timeout =
        std::chrono::milliseconds(int64_t(std::llround(connect_timeout_seconds * 1000)));
    const Clock::time_point until = Clock::now() + timeout;

    CoordinatorEndpoint endpoint;
    endpoint.address = effective_address();
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
        } else {
            // A coordinator writes its tokens before it listens: once it answers, a
            // token that is not here now will not appear, and waiting would only delay
            // the news. One that does not answer yet may be starting here.
            const bool answers =
                !std::filesystem::exists(local) &&
                port_answers(endpoint.address,
                             std::min(timeout, std::chrono::milliseconds(500)));
            if (answers ? !std::filesystem::exists(local) : !appears_by(local, until))
                throw CommandError(
                    "no " + name + " token: " +
                    (answers
                         ? "the coordinator at " + endpoint.address +
                               " answers, but this directory has no " + local.string() +
                               "; pass --token-file PATH (its DATA/" + name + ".token)"
                         : "pass --token-file PATH (the coordinator writes DATA/" + name +
                               ".token at its first start)") +
                    " or set ALIQUOT_TOKEN");
            endpoint.token = read_token_file(local);
        }
    } catch (const TokenError& e) {
        throw CommandError(e.what());
    }
    if (!tls_ca.empty()) endpoint.tls_ca_pem = read_tls_ca(tls_ca);
    // What the token file took is not waited again for the port: one timeout in all.
    endpoint.connect_timeout = std::max(
        std::chrono::milliseconds(0),
        std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now()));
    return endpoint;
}

}  // namespace aliquot::cli
