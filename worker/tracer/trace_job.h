// trace_sample_job: the one function that traces a SampleJob, for the embedded render and
// for a networked worker alike.
#pragma once

#include <atomic>
#include <stdexcept>

#include "path_tracer.h"
#include "sample_job.h"

namespace aliquot {

class JobCancelled : public std::runtime_error {
public:
    JobCancelled() : std::runtime_error("sample job cancelled") {}
};

// Traces a job with `threads` threads (rows are shared out; each pixel is traced by one
// thread, so the result does not depend on the count). When `cancel` becomes true the
// job stops between pixels and throws JobCancelled: a worker told to stop gives the lease
// back instead of finishing a long job.
SampleJobResult trace_sample_job(const PathTracer& tracer, const RenderGeometry& geometry,
                                 const SampleJob& job, int threads = 1,
                                 const std::atomic<bool>* cancel = nullptr);

}  // namespace aliquot
