// Running another program and waiting for it (the study's references, its report script).
#pragma once

#include <string>
#include <vector>

namespace aliquot {

// Runs argv[0] (looked up on PATH unless it contains a '/') with `argv` and waits; its
// stdout and stderr stay ours, so its progress and errors reach the user. Returns its
// exit status: 127 when it cannot be started (as a shell says), 128 + N when signal N
// ended it.
int run_process(const std::vector<std::string>& argv);

}  // namespace aliquot
