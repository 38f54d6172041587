#include "unix_millis.h"

#include <chrono>

namespace aliquot {

int64_t unix_millis_now() {
    using namespace std::chrono;
    return duration_cast<milliseconds>(system_clock::now().time_since_epoch()).count();
}

}  // namespace aliquot
