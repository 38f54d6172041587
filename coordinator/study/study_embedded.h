// The study's renders on an in-process coordinator with local tracing threads.
#pragma once

#include <filesystem>
#include <memory>

#include "study_backend.h"

namespace aliquot {

// Opens (and migrates) the database in `data_dir` itself.
std::unique_ptr<StudyBackend> make_embedded_backend(const std::filesystem::path& data_dir,
                                                    int threads);

}  // namespace aliquot
