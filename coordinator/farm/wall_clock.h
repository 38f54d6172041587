// Wall-clock milliseconds since the Unix epoch: what workers' "last seen" and a render's
// times are kept in.
#pragma once

#include <chrono>
#include <cstdint>

namespace aliquot {

inline int64_t wall_millis() {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

}  // namespace aliquot
