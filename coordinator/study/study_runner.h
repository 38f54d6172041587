// Runs a study's renders on a backend (embedded: one at a time on local threads, so each
// wall time is the render's own; a farm: all at once), measures each against its
// reference and records it in OUT/data/aliquot.db. Resumable: a render recorded with the
// same spec is never rendered again.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "study_backend.h"
#include "study_definition.h"

namespace aliquot {

struct StudyRunOptions {
    std::filesystem::path study_file;
    std::filesystem::path out;  // OUT: report here, database and images in OUT/data
    int threads = 0;  // tracing threads, embedded and for references (0: all cores)
    // Where the renders run, made once OUT/data exists and before the study opens its
    // database there. Null: the embedded coordinator.
    std::function<std::unique_ptr<StudyBackend>(const std::filesystem::path& data_dir)>
        backend;
    // Progress as units done of a total (1000 a render), with a note; then done().
    std::function<void(uint64_t done, uint64_t total, const std::string& note)> progress;
    std::function<void()> done;
};

struct StudyRunSummary {
    size_t renders = 0;   // keys in the study at this scale
    size_t rendered = 0;  // rendered by this run (the rest were recorded before)
    size_t reused = 0;    // keys whose spec equals another key's: the result is shared
    double seconds = 0;
};

// Throws StudyError (a failed render or reference, a scaled parameter gone invalid).
StudyRunSummary run_study(const StudyDefinition& def, const StudyScale& scale,
                          const StudyRunOptions& options);

}  // namespace aliquot
