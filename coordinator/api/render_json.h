// A render as JSON: the one spelling of RenderInfo, shared by the HTTP API (docs/API.md),
// `aliquot status | submit --json` (which read it from gRPC) and `aliquot render --json`.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator.h"

namespace aliquot {

// How much of the image the strategy's buckets have declared converged (Dammertz).
struct BucketProgress {
    size_t converged = 0, total = 0;
    double converged_area = 0;  // fraction of the image's pixels
};
BucketProgress bucket_progress(const std::vector<Bucket>& buckets, uint32_t width,
                               uint32_t height);

// The compact form used in lists and live events: no strategy parameters, no pixels.
// `buckets` (the HTTP API has them, a gRPC client does not) makes a Dammertz render's
// progress the converged area rather than samples over its cap.
nlohmann::json render_summary(
    const RenderInfo& info, const std::optional<BucketProgress>& buckets = std::nullopt);
// The summary plus strategy parameters, outcome and rays traced.
nlohmann::json render_detail(const RenderInfo& info,
                             const std::optional<BucketProgress>& buckets = std::nullopt);

// A render's event: {"seq", "at_ms", "kind", "fields": {...}} (GET
// /api/renders/{id}/events).
nlohmann::json event_json(const RenderEvent& event);

// Numbers as every document of the API writes them. Six significant digits are more than
// any chart or table shows, and half the bytes.
double short_number(double v);
// -1 is how the coordinator says "not measured"; JSON says null.
nlohmann::json measured(double v);
// A signed measure (a bias): null when absent or not finite, never a JSON NaN.
nlohmann::json measured(const std::optional<double>& v);

}  // namespace aliquot
