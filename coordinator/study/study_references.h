// The references a study's renders are measured against: one per scene and size, rendered
// once by `aliquot reference` and kept in a cache named by the scene's content.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "image.h"
#include "study_plan.h"

namespace aliquot {

struct StudyReference {
    std::filesystem::path path;
    Image image;
    // For scenes with oracle renders: the per-sample sigma of a second high-spp render of
    // its own seed (kSigmaSeed), never the judged render's nor the reference's.
    std::shared_ptr<const std::vector<float>> sigma;
};

// The seed of the oracle's sigma renders: beside the references' 2^40, far from any seed
// a study's renders use.
constexpr uint64_t kSigmaSeed = (uint64_t(1) << 40) + 1;

// Keyed by reference_key. Renders the missing ones first, so a failure comes early.
using StudyReferences = std::map<std::string, StudyReference>;

std::string reference_key(const StudyRender& render);

// Renders each missing reference with this binary's `reference` command (its progress
// stays on stderr) into `dir`, then reads them all; and, where a scene and size has an
// oracle render, its sigma render (`render --aovs`, same spp, kSigmaSeed). Throws
// StudyError.
StudyReferences prepare_references(const std::vector<StudyRender>& renders,
                                   const std::filesystem::path& study_file,
                                   const std::filesystem::path& dir, uint64_t spp,
                                   int threads);

// The scene as the renders need it: a built-in name, or a file relative to the study
// file.
std::string resolve_scene(const std::string& scene,
                          const std::filesystem::path& study_file);

// Letters, digits, '-' and '.' kept, the rest '_': a key as a file name.
std::string safe_file_name(const std::string& s);

}  // namespace aliquot
