// JobFailures: one render's jobs that its workers could not trace, and what its
// FailurePolicy makes of them (docs/FARM.md, "A job no worker can trace"): the job goes
// to another worker, a worker that keeps failing is kept off the render, or the render
// fails with the reason.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "sample_job.h"

namespace aliquot {

// Soft-fail, then another worker, then fail the render with the reason.
struct FailurePolicy {
    // A job that failed on this many distinct workers fails its render; so does a job
    // that failed this many times in all when no live worker it has not failed on is
    // left.
    uint32_t max_job_failures = 3;
    // A worker with this many failures on one render gets no more of its jobs while a
    // live worker with fewer can take them.
    uint32_t blocklist_after = 2;
    // Whether a job that failed max_job_failures times fails its render when fewer hosts
    // than that failed it and no other live host could take it (a farm on fewer machines
    // than max_job_failures). Off, only max_job_failures distinct hosts fail a render, so
    // that no single holder of the worker token can fail one alone; such a job is then
    // retried until the render is cancelled. The workers named here are hosts
    // (Coordinator: the address a worker's connection came from).
    bool fail_on_fewer_hosts = true;
};

class JobFailures {
public:
    // One job's failures, this round.
    struct OfJob {
        std::vector<std::string> failed_on;  // distinct workers
        uint32_t failures = 0;               // in all
    };

    // Counts a failure of `job` (of rectangle `rect`) on `worker`, for `reason`. Returns
    // the reason its render fails with when the policy says so, empty when the job is to
    // be traced again.
    std::string count(OfJob& job, const PixelRect& rect, const std::string& worker,
                      const std::string& reason, const std::set<std::string>& alive,
                      const FailurePolicy& policy);
    // Whether `worker` gets none of the render's jobs while someone else in `alive` can
    // trace them.
    bool kept_off(const std::string& worker, const std::set<std::string>& alive,
                  const FailurePolicy& policy) const;
    // Whether `worker` may take `job`: one it failed on waits for another in `alive`.
    bool may_take(const OfJob& job, const std::string& worker,
                  const std::set<std::string>& alive, const FailurePolicy& policy) const;
    // Failures of `worker` on the render's jobs.
    uint32_t of(const std::string& worker) const;

private:
    bool blocklisted(const std::string& worker, const FailurePolicy& policy) const;
    // Whether someone in `alive` but `worker` may take `job`: not blocklisted and not
    // among those it failed on.
    bool another_could_take(const OfJob& job, const std::string& worker,
                            const std::set<std::string>& alive,
                            const FailurePolicy& policy) const;

    std::map<std::string, uint32_t> by_worker_;  // the blocklist's counts
};

}  // namespace aliquot
