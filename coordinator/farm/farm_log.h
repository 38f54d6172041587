// One line on stderr for what the farm cannot do and goes on without (a write that
// failed, a render that cannot resume).
#pragma once

#include <cstdio>
#include <string>

namespace aliquot {

inline void log_farm_error(const std::string& what) {
    std::fprintf(stderr, "coordinator: %s\n", what.c_str());
}

}  // namespace aliquot
