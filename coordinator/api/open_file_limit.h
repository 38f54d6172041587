// The process's open-file limit, raised as far as it may go: every gRPC and HTTP
// connection holds a descriptor, and a listener that runs out of them stops accepting
// (docs/SECURITY.md, "gRPC listener").
#pragma once

#include <cstdint>

namespace aliquot {

// Raises the soft RLIMIT_NOFILE to the hard one (what an unprivileged process may);
// returns the soft limit now in force.
uint64_t raise_open_file_limit();

}  // namespace aliquot
