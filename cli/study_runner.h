// StudyRunner: runs a study's renders embedded (one at a time on local threads, so each
// wall time is the render's own) or on a farm (all at once, in parallel across workers),
// measures each against its reference and records it in OUT/data/aliquot.db. Resumable:
// a render recorded with the same spec is never rendered again.
#pragma once

#include <filesystem>
#include <string>

#include "study.h"

namespace aliquot::cli {

struct StudyRunOptions {
    std::filesystem::path study_file;
    std::filesystem::path out;  // OUT: report here, database and images in OUT/data
    std::string coordinator;    // empty: embedded
    int threads = 0;            // embedded tracing threads (0: all cores)
};

struct StudyRunSummary {
    size_t renders = 0;   // keys in the study at this scale
    size_t rendered = 0;  // rendered by this run (the rest were recorded before)
    size_t reused = 0;    // keys whose spec equals another key's: the result is shared
    double seconds = 0;
};

// Throws CommandError (bad options, a failed render) or StudyError.
StudyRunSummary run_study(const StudyDefinition& def, const StudyScale& scale,
                          const StudyRunOptions& options);

}  // namespace aliquot::cli
