// The study's renders on a farm: the study's StudyBackend over the CLI's gRPC client. The
// one file where the study meets the client API.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "channel.h"
#include "study_backend.h"

namespace aliquot::cli {

// Fetched images go to `data_dir`/renders/farm-ID/image.exr.
std::unique_ptr<StudyBackend> make_farm_backend(const CoordinatorEndpoint& endpoint,
                                                const std::filesystem::path& data_dir);

}  // namespace aliquot::cli
