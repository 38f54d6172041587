// Whether something accepts TCP connections at a gRPC address, asked once and briefly: a
// client tells a coordinator that is up (its tokens are written before it listens) from
// one that may still be starting.
#pragma once

#include <chrono>
#include <string>

namespace aliquot::cli {

// True when a TCP connection to `address` ("host:port", "[v6]:port", optionally with
// gRPC's "dns:" or "ipv4:"/"ipv6:" scheme) is accepted within `within`. False for an
// address of another form (a unix socket) or one that does not resolve.
bool port_answers(const std::string& address, std::chrono::milliseconds within);

}  // namespace aliquot::cli
