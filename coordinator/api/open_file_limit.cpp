#include "open_file_limit.h"

#include <sys/resource.h>

#include <fstream>

namespace aliquot {

uint64_t raise_open_file_limit() {
    rlimit limit{};
    if (getrlimit(RLIMIT_NOFILE, &limit) != 0) return 0;
    rlim_t target = limit.rlim_max;
    // An unlimited hard limit is still capped by the kernel's fs.nr_open.
    if (target == RLIM_INFINITY) {
        unsigned long long nr_open = 1 << 20;
        std::ifstream("/proc/sys/fs/nr_open") >> nr_open;
        target = rlim_t(nr_open);
    }
    if (limit.rlim_cur < target) {
        rlimit raised = limit;
        raised.rlim_cur = target;
        if (setrlimit(RLIMIT_NOFILE, &raised) == 0) limit = raised;
    }
    return limit.rlim_cur;
}

}  // namespace aliquot
