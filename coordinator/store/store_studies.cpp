// RunStore's studies (docs/STUDIES.md): a study's definition, its renders' links and
// what each render measured.
#include "store.h"

#include <cmath>

#include "store_internal.h"

namespace aliquot {

using store_internal::or_null;

void RunStore::put_study(const StudyRecord& study) {
    std::lock_guard lock(mutex_);
    query(
        "INSERT INTO studies (id, name, definition_json, created_at) VALUES (?, ?, ?, ?)"
        " ON CONFLICT (id) DO UPDATE SET name = excluded.name,"
        " definition_json = excluded.definition_json",
        "record study " + study.id)
        .bind(study.id)
        .bind(study.name)
        .bind(study.definition_json)
        .bind(study.created_at)
        .run();
}

std::optional<StudyRecord> RunStore::get_study(const std::string& id) {
    std::lock_guard lock(mutex_);
    Query q =
        query("SELECT id, name, definition_json, created_at FROM studies WHERE id = ?",
              "read study " + id);
    if (!q.bind(id).step()) return std::nullopt;
    return StudyRecord{q.text(0), q.text(1), q.text(2), q.int64(3)};
}

void RunStore::link_study_render(const std::string& study_id,
                                 const std::string& render_id) {
    std::lock_guard lock(mutex_);
    query(
        "INSERT INTO study_renders (study_id, render_id) VALUES (?, ?)"
        " ON CONFLICT DO NOTHING",
        "link render " + render_id + " to study " + study_id)
        .bind(study_id)
        .bind(render_id)
        .run();
}

void RunStore::put_study_result(const StudyResult& r) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "INSERT INTO study_results (study_id, render_key, spec_json, origin, remote_id,"
        " render_id, state, samples, rays, seconds, samples_per_second, mean_abs, rmse,"
        " relative_mse, max_bucket, p99_bucket, outcome_json, updated_at,"
        " denoised_mean_abs, denoised_rmse, denoised_relative_mse, mean_bias,"
        " mean_bias_se, denoised_mean_bias, denoised_mean_bias_se)"
        " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?,"
        " ?)"
        " ON CONFLICT (study_id, render_key) DO UPDATE SET spec_json = "
        "excluded.spec_json,"
        " origin = excluded.origin, remote_id = excluded.remote_id,"
        " render_id = excluded.render_id, state = excluded.state,"
        " samples = excluded.samples, rays = excluded.rays, seconds = excluded.seconds,"
        " samples_per_second = excluded.samples_per_second, mean_abs = excluded.mean_abs,"
        " rmse = excluded.rmse, relative_mse = excluded.relative_mse,"
        " max_bucket = excluded.max_bucket, p99_bucket = excluded.p99_bucket,"
        " outcome_json = excluded.outcome_json, updated_at = excluded.updated_at,"
        " denoised_mean_abs = excluded.denoised_mean_abs,"
        " denoised_rmse = excluded.denoised_rmse,"
        " denoised_relative_mse = excluded.denoised_relative_mse,"
        " mean_bias = excluded.mean_bias, mean_bias_se = excluded.mean_bias_se,"
        " denoised_mean_bias = excluded.denoised_mean_bias,"
        " denoised_mean_bias_se = excluded.denoised_mean_bias_se",
        "record render " + r.render_key + " of study " + r.study_id);
    if (r.state != "submitted" && r.state != "done")
        q.refuse("state must be submitted or done, not '" + r.state + "'");
    const auto finite = [](const std::optional<double>& v) {
        return v && std::isfinite(*v) ? v : std::nullopt;
    };
    q.bind(r.study_id)
        .bind(r.render_key)
        .bind(r.spec_json)
        .bind(r.origin)
        .bind(r.remote_id)
        .bind(or_null(r.render_id))
        .bind(r.state)
        .bind(r.samples)
        .bind(r.rays)
        .bind(std::isfinite(r.seconds) ? r.seconds : 0.0)
        .bind(std::isfinite(r.samples_per_second) ? r.samples_per_second : 0.0)
        .bind(finite(r.mean_abs))
        .bind(finite(r.rmse))
        .bind(finite(r.relative_mse))
        .bind(finite(r.max_bucket))
        .bind(finite(r.p99_bucket))
        .bind(or_null(r.outcome_json))
        .bind(r.updated_at)
        .bind(finite(r.denoised_mean_abs))
        .bind(finite(r.denoised_rmse))
        .bind(finite(r.denoised_relative_mse))
        .bind(finite(r.mean_bias))
        .bind(finite(r.mean_bias_se))
        .bind(finite(r.denoised_mean_bias))
        .bind(finite(r.denoised_mean_bias_se))
        .run();
}

std::vector<StudyResult> RunStore::study_results(const std::string& study_id) {
    std::lock_guard lock(mutex_);
    Query q = query(
        "SELECT study_id, render_key, spec_json, origin, remote_id, render_id, state, "
        "samples,"
        " rays, seconds, samples_per_second, mean_abs, rmse, relative_mse, max_bucket,"
        " p99_bucket, outcome_json, updated_at, denoised_mean_abs, denoised_rmse,"
        " denoised_relative_mse, mean_bias, mean_bias_se, denoised_mean_bias,"
        " denoised_mean_bias_se FROM study_results WHERE study_id = ?"
        " ORDER BY rowid",
        "read the renders of study " + study_id);
    q.bind(study_id);
    std::vector<StudyResult> out;
    while (q.step()) {
        StudyResult r;
        r.study_id = q.text(0);
        r.render_key = q.text(1);
        r.spec_json = q.text(2);
        r.origin = q.text(3);
        r.remote_id = q.text(4);
        r.render_id = q.text(5);
        r.state = q.text(6);
        r.samples = q.int64(7);
        r.rays = q.int64(8);
        r.seconds = q.real(9);
        r.samples_per_second = q.real(10);
        r.mean_abs = q.maybe_real(11);
        r.rmse = q.maybe_real(12);
        r.relative_mse = q.maybe_real(13);
        r.max_bucket = q.maybe_real(14);
        r.p99_bucket = q.maybe_real(15);
        r.outcome_json = q.text(16);
        r.updated_at = q.int64(17);
        r.denoised_mean_abs = q.maybe_real(18);
        r.denoised_rmse = q.maybe_real(19);
        r.denoised_relative_mse = q.maybe_real(20);
        r.mean_bias = q.maybe_real(21);
        r.mean_bias_se = q.maybe_real(22);
        r.denoised_mean_bias = q.maybe_real(23);
        r.denoised_mean_bias_se = q.maybe_real(24);
        out.push_back(std::move(r));
    }
    return out;
}

void RunStore::remove_study_result(const std::string& study_id,
                                   const std::string& render_key) {
    std::lock_guard lock(mutex_);
    query("DELETE FROM study_results WHERE study_id = ? AND render_key = ?",
          "forget render " + render_key + " of study " + study_id)
        .bind(study_id)
        .bind(render_key)
        .run();
}

}  // namespace aliquot
