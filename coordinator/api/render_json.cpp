#include "render_json.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "seed_json.h"

namespace aliquot {

using nlohmann::json;

namespace {

json parse_or_empty(const std::string& text) {
    if (text.empty()) return json::object();
    const json j = json::parse(text, nullptr, false);
    return j.is_discarded() ? json::object() : j;
}

double progress_of(const RenderInfo& info, const std::optional<BucketProgress>& buckets) {
    if (info.state == RenderState::Done) return 1;
    // Dammertz stops where buckets converge: its planned samples are only a cap.
    if (buckets && buckets->total > 0) return buckets->converged_area;
    if (info.samples_planned == 0) return 0;
    return std::min(1.0, double(info.samples_done) / double(info.samples_planned));
}

}  // namespace

double short_number(double v) {
    if (!std::isfinite(v) || v == 0) return v;
    char text[32];
    std::snprintf(text, sizeof text, "%.6g", v);
    return std::strtod(text, nullptr);
}

json measured(double v) {
    return (v >= 0 && std::isfinite(v)) ? json(short_number(v)) : json(nullptr);
}

json measured(const std::optional<double>& v) {
    return (v && std::isfinite(*v)) ? json(short_number(*v)) : json(nullptr);
}

BucketProgress bucket_progress(const std::vector<Bucket>& buckets, uint32_t width,
                               uint32_t height) {
    BucketProgress p;
    p.total = buckets.size();
    uint64_t area = 0;
    for (const Bucket& b : buckets)
        if (b.converged) {
            ++p.converged;
            area += b.rect.size();
        }
    const uint64_t pixels = uint64_t(width) * height;
    p.converged_area = pixels ? double(area) / double(pixels) : 0;
    return p;
}

json render_summary(const RenderInfo& info,
                    const std::optional<BucketProgress>& buckets) {
    json j = {{"id", info.id},
              {"name", info.name},
              {"scene", info.scene_name},
              {"method", info.method},
              {"state", to_string(info.state)},
              {"width", info.width},
              {"height", info.height},
              {"seed", seed_to_json(info.seed)},
              {"priority", info.priority},
              {"queue_position", info.queue_position},
              {"samples_done", info.samples_done},
              {"samples_planned", info.samples_planned},
              {"rounds", info.rounds_done},
              {"seconds", short_number(info.seconds)},
              {"samples_per_second", short_number(info.samples_per_second)},
              {"error_estimate", measured(info.error_estimate)},
              {"error_vs_reference", measured(info.error_vs_reference)},
              {"mean_bias", measured(info.mean_bias)},
              {"mean_bias_se", measured(info.mean_bias_se)},
              {"created_ms", info.created_ms},
              {"progress", progress_of(info, buckets)}};
    if (!info.error.empty()) j["error"] = info.error;
    if (info.finished_ms) j["finished_ms"] = info.finished_ms;
    if (buckets && buckets->total > 0) {
        j["buckets_converged"] = buckets->converged;
        j["buckets_total"] = buckets->total;
    }
    return j;
}

json event_json(const RenderEvent& e) {
    return {{"seq", e.seq},
            {"at_ms", e.at_ms},
            {"kind", to_string(e.kind)},
            {"fields", json::parse(fields_json(e.fields), nullptr, false)}};
}

json render_detail(const RenderInfo& info, const std::optional<BucketProgress>& buckets) {
    json j = render_summary(info, buckets);
    j["strategy"] = parse_or_empty(info.strategy_json);
    j["outcome"] = parse_or_empty(info.outcome_json);
    j["rays"] = info.rays;
    return j;
}

}  // namespace aliquot
