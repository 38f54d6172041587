#include "open_file_limit.h"

#include <sys/resource.h>

namespace aliquot {

uint64_t raise_open_file_limit() {
    rlimit limit{};
    if (getrlimit(RLIMIT_NOFILE, &limit) != 0) return 0;
    if (limit.rlim_cur < limit.rlim_max) {
        rlimit raised = limit;
        raised.rlim_cur = limit.rlim_max;
        // A hard limit of RLIM_INFINITY may still be above what the kernel allows
        // (fs.nr_open): then the soft limit stays where it was.
        if (setrlimit(RLIMIT_NOFILE, &raised) == 0) limit = raised;
    }
    return limit.rlim_cur;
}

}  // namespace aliquot
