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

// Traces a job with `threads` threads. Its samples are traced in batches of a cell's
// samples (kCellSide in sample_job.h), and threads share out whole cells, so the result
// does not depend on the thread count, nor, for a job whose rectangle is cut on cell
// boundaries (as round_cutter cuts them), on how the round was cut into jobs. A rectangle
// that cuts through cells (the network may send any) is still traced correctly, its
// cells clipped to it: only its samples' last bits may then differ from those of a cut on
// cells. When `cancel` becomes true the job stops between batches and throws
// JobCancelled: a worker told to stop gives the lease back instead of finishing a long
// job.
SampleJobResult trace_sample_job(const PathTracer& tracer, const RenderGeometry& geometry,
                                 const SampleJob& job, int threads = 1,
                                 const std::atomic<bool>* cancel = nullptr);

}  // namespace aliquot
