#include "study_recorder.h"

#include <nlohmann/json.hpp>

namespace aliquot {

using nlohmann::json;

StudyRecorder::StudyRecorder(RunStore& store, std::string id)
    : store_(store), id_(std::move(id)) {
    for (StudyResult& r : store_.study_results(id_))
        results_[r.render_key] = std::move(r);
}

void StudyRecorder::record_study(const StudyDefinition& def, const StudyScale& scale,
                                 uint64_t reference_spp, uint32_t metric_bucket,
                                 const std::filesystem::path& study_file) {
    const json details = {
        {"definition", def.source},
        {"scale",
         {{"name", scale.name},
          {"max_side", scale.max_side},
          {"spp_factor", scale.spp_factor},
          {"reference_spp", reference_spp},
          {"metric_bucket", metric_bucket}}},
        // As given (studies/x.json), so the report can say how to re-run it.
        {"study_file", study_file.is_absolute()
                           ? study_file.filename().string()
                           : study_file.lexically_normal().string()}};
    store_.put_study({id_, def.name, details.dump(), unix_millis_now()});
}

const StudyResult* StudyRecorder::find(const std::string& key) const {
    const auto it = results_.find(key);
    return it == results_.end() ? nullptr : &it->second;
}

void StudyRecorder::record(StudyResult row) {
    row.study_id = id_;
    row.updated_at = unix_millis_now();
    store_.put_study_result(row);
    results_[row.render_key] = std::move(row);
}

void StudyRecorder::record_submitted(const std::string& key, const std::string& spec_json,
                                     const std::string& origin,
                                     const std::string& remote_id) {
    StudyResult row;
    row.render_key = key;
    row.spec_json = spec_json;
    row.origin = origin;
    row.remote_id = remote_id;
    row.state = "submitted";
    record(row);
}

void StudyRecorder::record_done(const std::string& key, const CollectedRender& c,
                                const ErrorMetrics& m,
                                const std::optional<ErrorMetrics>& denoised) {
    StudyResult row = results_.at(key);
    row.render_id = c.local_id;
    row.state = "done";
    row.samples = int64_t(c.samples);
    row.rays = int64_t(c.rays);
    row.seconds = c.seconds;
    row.samples_per_second = c.seconds > 0 ? double(c.samples) / c.seconds : 0;
    row.mean_abs = m.mean_abs;
    row.rmse = m.rmse;
    row.relative_mse = m.relative_mse;
    row.max_bucket = m.max_bucket;
    row.p99_bucket = m.p99_bucket;
    row.mean_bias = m.mean_bias;  // NaN (a black reference) is stored as NULL
    row.mean_bias_se = m.mean_bias_se;
    row.outcome_json = c.outcome_json;
    if (denoised) {
        row.denoised_mean_abs = denoised->mean_abs;
        row.denoised_rmse = denoised->rmse;
        row.denoised_relative_mse = denoised->relative_mse;
        row.denoised_mean_bias = denoised->mean_bias;
        row.denoised_mean_bias_se = denoised->mean_bias_se;
    }
    store_.link_study_render(id_, c.local_id);
    record(row);
}

void StudyRecorder::forget_unless(const std::map<std::string, size_t>& keys) {
    for (const auto& [key, row] : results_)
        if (!keys.count(key)) store_.remove_study_result(id_, key);
}

}  // namespace aliquot
