// The record of a study run in the study's database: the study itself, and per render key
// its state, where it runs and its measurements. What makes a run resumable.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "error_metric.h"
#include "store.h"
#include "study_backend.h"
#include "study_definition.h"

namespace aliquot {

class StudyRecorder {
public:
    // Loads what earlier runs of study `id` recorded.
    StudyRecorder(RunStore& store, std::string id);

    // The definition and scale, as the report reads them.
    void record_study(const StudyDefinition& def, const StudyScale& scale,
                      uint64_t reference_spp, uint32_t metric_bucket,
                      const std::filesystem::path& study_file);

    RunStore& store() { return store_; }
    const std::map<std::string, StudyResult>& results() const { return results_; }
    const StudyResult* find(const std::string& key) const;
    void record(StudyResult row);
    void record_submitted(const std::string& key, const std::string& spec_json,
                          const std::string& origin, const std::string& remote_id);
    // `denoised`: the metrics after denoising, when the study denoises.
    void record_done(const std::string& key, const CollectedRender& render,
                     const ErrorMetrics& metrics,
                     const std::optional<ErrorMetrics>& denoised = std::nullopt);
    // Keys the file no longer has (edited since an earlier run) leave the study's
    // results; their renders stay in the database.
    void forget_unless(const std::map<std::string, size_t>& keys);

private:
    RunStore& store_;
    std::string id_;
    std::map<std::string, StudyResult> results_;
};

}  // namespace aliquot
