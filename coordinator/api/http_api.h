// The documents of the coordinator's HTTP API (docs/API.md), apart from any transport:
// rounds, buckets and workers as JSON (renders are render_json.h's), the submit request's
// parsing, and the compact images the dashboard draws (a tone-mapped PNG preview,
// quantised per-pixel maps).
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator.h"
#include "render_json.h"

namespace aliquot {
class Accumulator;
}

namespace aliquot::http_api {

// A request the API refuses, with the HTTP status to answer (400, 404, ...).
class ApiError : public std::runtime_error {
public:
    ApiError(int status, const std::string& message)
        : std::runtime_error(message), status_(status) {}
    int status() const { return status_; }

private:
    int status_;
};

nlohmann::json round_json(const RoundSummary& round);
// The same as a row [index, samples_in_round, samples_total, seconds, error_estimate,
// error_vs_reference, mean_bias, mean_bias_se]: a render may have thousands of rounds.
nlohmann::json round_row(const RoundSummary& round);
extern const char* const kRoundColumns[8];
nlohmann::json worker_json(const WorkerStatus& worker);
// Buckets as [x, y, width, height, error, converged] rows.
nlohmann::json buckets_json(const std::vector<Bucket>& buckets);

// Parses the body of POST /api/renders into a spec (built-in scenes only: an HTTP client
// must not make the coordinator read its own files). Throws ApiError(400) naming the
// field. Ranges (resolution, budget, method parameters) are the coordinator's to check on
// submit.
RenderSpec parse_render_request(const std::string& body);

// An 8-bit sRGB PNG of the image scaled by 2^exposure, box-filtered down so that its
// longer side is at most `max_side`.
std::string preview_png(const Image& image, double exposure, uint32_t max_side);
// The same PNG at exposure 0 made straight from a render's sums, without a full-size
// image: what a thumbnail of a render in memory is (it holds only the small image).
std::string thumbnail_png(const Accumulator& sums, uint32_t max_side);

enum class MapKind { Spp, Error };
// A per-pixel map, box-filtered to at most `max_side` on the longer side and quantised to
// bytes: value = lo + (hi - lo) * byte / 255, as base64 in "data". `image` must carry the
// sample-count and variance layers (aov_channels.h, Accumulator::image(true)); the error
// is the standard error of each pixel's mean luminance, sqrt(variance).
nlohmann::json pixel_map(const Image& image, MapKind kind, uint32_t max_side);

// Query-parameter parsing that answers 400 rather than throwing anything else.
double number_param(const std::string& name, const std::string& text, double lo,
                    double hi);

std::string base64(const std::string& bytes);

// ---- cross-site requests (docs/SECURITY.md) ----

// Which Host headers the server answers, against DNS rebinding: a page on an attacker's
// name that resolves to this server sends that name as Host and is refused.
//   - the listen address itself, host:port (IPv6 as [addr]:port);
//   - localhost, 127.0.0.1 and [::1] on any port, when listening on loopback or on every
//     interface (0.0.0.0, ::, or no host): a foreign page cannot be served under these
//     names, and a forwarded or published port (kubectl port-forward, docker -p) may
//     differ from the one listened on;
//   - when listening on every interface, any IP literal on any port: a rebinding needs a
//     DNS name, and a published or forwarded port may differ from the one listened on;
//   - each allowed entry: "NAME" (that name on any port) or "NAME:PORT" (that port only).
// Names compare case-insensitively, with a trailing dot ignored.
class HostPolicy {
public:
    // Throws std::invalid_argument for an allowed entry that is not NAME or NAME:PORT.
    HostPolicy(const std::string& listen_host, int port,
               const std::vector<std::string>& allowed);
    bool allows(const std::string& host_header) const;
    // What is allowed, for the refusal's message.
    std::string describe() const;

private:
    struct Entry {
        std::string name;
        int port;  // -1: any
    };
    std::vector<Entry> entries_;
    bool any_ip_literal_ = false;
};

// Whether a Content-Type header names application/json (parameters such as charset
// allowed, case-insensitive).
bool is_json_content_type(const std::string& content_type);

// Whether an Origin header names the site the request's Host header names, served over
// HTTP ("http://" + host, a default :80 ignored) or, when `https`, over HTTPS
// ("https://" + host, a default :443 ignored); case is ignored. A page served over one
// scheme is another origin than the same host over the other.
bool origin_matches_host(const std::string& origin, const std::string& host, bool https);

// The body of POST /api/renders/{id}/cancel: a JSON object with no fields, "{}".
void parse_cancel_request(const std::string& body);
// The body of PATCH /api/renders/{id}: {"priority": N}, nothing else. Throws
// ApiError(400).
int32_t parse_priority_request(const std::string& body);

}  // namespace aliquot::http_api
