#include "http_api.h"

#include <arpa/inet.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "accumulator.h"
#include "aov_channels.h"
#include "png_encoder.h"
#include "resolution.h"
#include "scene_loader.h"
#include "seed_json.h"

namespace aliquot::http_api {

using nlohmann::json;

namespace {

const Image::Channel* channel(const Image& image, const std::string& name) {
    for (const Image::Channel& c : image.extra)
        if (c.name == name) return &c;
    return nullptr;
}

// Box-filters a one-value-per-pixel plane by an integer factor so the longer side fits.
struct Plane {
    uint32_t width = 0, height = 0;
    std::vector<double> values;
};

uint32_t shrink_factor(uint32_t width, uint32_t height, uint32_t max_side) {
    const uint32_t side = std::max(width, height);
    max_side = std::max<uint32_t>(max_side, 1);
    return std::max<uint32_t>(1, (side + max_side - 1) / max_side);
}

template <typename Get>
Plane downsample(uint32_t width, uint32_t height, uint32_t factor, Get get) {
    Plane p;
    p.width = (width + factor - 1) / factor;
    p.height = (height + factor - 1) / factor;
    p.values.assign(size_t(p.width) * p.height, 0.0);
    std::vector<uint32_t> counts(p.values.size(), 0);
    for (uint32_t y = 0; y < height; ++y)
        for (uint32_t x = 0; x < width; ++x) {
            const size_t o = size_t(y / factor) * p.width + x / factor;
            p.values[o] += get(size_t(y) * width + x);
            ++counts[o];
        }
    for (size_t i = 0; i < p.values.size(); ++i) p.values[i] /= counts[i];
    return p;
}

uint8_t srgb_byte(double linear) {
    if (!(linear > 0)) return 0;  // also NaN
    const double v = linear <= 0.0031308 ? 12.92 * linear
                                         : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
    return uint8_t(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
}

void require(bool ok, const std::string& message) {
    if (!ok) throw ApiError(400, message);
}

// A priority: a whole number in int32's range, negative allowed.
int32_t priority_number(const json& v) {
    require(v.is_number_integer(), "'priority' must be a whole number");
    const int64_t p = v.is_number_unsigned() ? (v.get<uint64_t>() > uint64_t(INT32_MAX)
                                                    ? int64_t(INT32_MAX) + 1
                                                    : int64_t(v.get<uint64_t>()))
                                             : v.get<int64_t>();
    require(p >= INT32_MIN && p <= INT32_MAX, "'priority' must be between " +
                                                  std::to_string(INT32_MIN) + " and " +
                                                  std::to_string(INT32_MAX));
    return int32_t(p);
}

uint64_t whole_number(const json& v, const std::string& field, uint64_t top) {
    if (v.is_number_unsigned() && v.get<uint64_t>() <= top) return v.get<uint64_t>();
    if (v.is_number_integer() && v.get<int64_t>() >= 0 &&
        uint64_t(v.get<int64_t>()) <= top)
        return uint64_t(v.get<int64_t>());
    if (v.is_number_float()) {
        const double d = v.get<double>();
        if (d >= 0 && d <= double(top) && d == std::floor(d)) return uint64_t(d);
    }
    throw ApiError(
        400, "'" + field + "' must be a whole number from 0 to " + std::to_string(top));
}

}  // namespace

const char* const kRoundColumns[8] = {
    "index",          "samples_in_round",   "samples_total", "seconds",
    "error_estimate", "error_vs_reference", "mean_bias",     "mean_bias_se"};

json round_json(const RoundSummary& r) {
    const json row = round_row(r);
    json j = json::object();
    for (size_t i = 0; i < row.size(); ++i) j[kRoundColumns[i]] = row[i];
    return j;
}

json round_row(const RoundSummary& r) {
    return json::array({r.index, r.samples_in_round, r.samples_total,
                        short_number(r.seconds), measured(r.error_estimate),
                        measured(r.error_vs_reference), measured(r.mean_bias),
                        measured(r.mean_bias_se)});
}

json worker_json(const WorkerStatus& w) {
    return {{"name", w.name},
            {"threads", w.threads},
            {"state", w.state},
            {"leases", w.leases},
            {"samples_traced", w.samples_traced},
            {"samples_per_second", short_number(w.samples_per_second)},
            {"last_seen_ms", w.last_seen_ms},
            {"host", w.host},
            {"version", w.version},
            {"failures", w.failures}};
}

json buckets_json(const std::vector<Bucket>& buckets) {
    json rows = json::array();
    for (const Bucket& b : buckets)
        rows.push_back(
            {b.rect.x, b.rect.y, b.rect.width, b.rect.height,
             std::isfinite(b.error) ? json(short_number(b.error)) : json(nullptr),
             b.converged ? 1 : 0});
    return rows;
}

RenderSpec parse_render_request(const std::string& body) {
    const json j = json::parse(body, nullptr, false);
    require(!j.is_discarded(), "request body is not valid JSON");
    require(j.is_object(), "request body must be a JSON object");
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    bool have_resolution = false, have_width = false, have_height = false;
    for (const auto& [key, v] : j.items()) {
        if (key == "scene") {
            require(v.is_string(), "'scene' must be a string");
            spec.scene_name = v.get<std::string>();
        } else if (key == "resolution") {
            require(v.is_string(), "'resolution' must be a string like \"256x256\"");
            try {
                const Resolution r = parse_resolution(v.get<std::string>());
                spec.width = r.width;
                spec.height = r.height;
            } catch (const std::invalid_argument& e) {
                throw ApiError(400, std::string("'resolution': ") + e.what());
            }
            have_resolution = true;
        } else if (key == "width") {
            spec.width = uint32_t(whole_number(v, key, UINT32_MAX));
            have_width = true;
        } else if (key == "height") {
            spec.height = uint32_t(whole_number(v, key, UINT32_MAX));
            have_height = true;
        } else if (key == "seed") {
            try {
                spec.seed = seed_from_json(v);
            } catch (const std::invalid_argument& e) {
                throw ApiError(400, std::string("'seed': ") + e.what());
            }
        } else if (key == "priority") {
            spec.priority = priority_number(v);
        } else if (key == "name") {
            require(v.is_string(), "'name' must be a string");
            spec.name = v.get<std::string>();
        } else if (key == "albedo_normal") {
            require(v.is_boolean(), "'albedo_normal' must be true or false");
            spec.aux = v.get<bool>();
        } else if (key == "strategy") {
            try {
                spec.strategy = v.get<StrategyParams>();
            } catch (const std::exception& e) {
                throw ApiError(400, std::string("strategy: ") + e.what());
            }
        } else {
            throw ApiError(400,
                           "unknown field '" + key +
                               "'; expected scene, resolution (or width and height), "
                               "seed, strategy, priority, name, albedo_normal");
        }
    }
    require(!(have_resolution && (have_width || have_height)),
            "give 'resolution' or 'width' and 'height', not both");
    if (!have_resolution) {
        require(have_width == have_height, "'width' and 'height' go together");
        if (!have_width) spec.width = spec.height = 256;
    }
    // As on the command line: a render that needs a budget and was given none gets 64
    // samples per pixel, whatever its method (the dashboard's form leaves defaults out).
    if (needs_budget(spec.strategy.method) && spec.strategy.spp == 0 &&
        spec.strategy.budget == 0)
        spec.strategy.spp = kDefaultSpp;

    const std::vector<std::string> names = builtin_scene_names();
    if (std::find(names.begin(), names.end(), spec.scene_name) == names.end()) {
        std::string list;
        for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
        throw ApiError(
            400, "unknown scene '" + spec.scene_name + "'; built-in scenes: " + list);
    }
    spec.scene_json = self_contained_scene_json(spec.scene_name);
    return spec;
}

namespace {

// An 8-bit sRGB PNG of a width x height image whose pixel i `rgb(i, out)` gives, scaled
// by 2^exposure and box-filtered so that its longer side is at most `max_side`, in one
// pass that holds only the small image: what preview_png does to an Image and
// thumbnail_png to a render's sums.
template <typename Rgb>
std::string shrunk_png(uint32_t width, uint32_t height, double exposure,
                       uint32_t max_side, Rgb rgb) {
    const double scale = std::exp2(exposure);
    const uint32_t f = shrink_factor(width, height, max_side);
    const uint32_t w = (width + f - 1) / f, h = (height + f - 1) / f;
    std::vector<double> sums(size_t(w) * h * 3, 0.0);
    std::vector<uint32_t> counts(size_t(w) * h, 0);
    for (uint32_t y = 0; y < height; ++y)
        for (uint32_t x = 0; x < width; ++x) {
            float v[3];
            rgb(size_t(y) * width + x, v);
            const size_t o = size_t(y / f) * w + x / f;
            for (int c = 0; c < 3; ++c) sums[o * 3 + c] += double(v[c]);
            ++counts[o];
        }
    std::vector<uint8_t> bytes(sums.size());
    for (size_t i = 0; i < sums.size(); ++i)
        bytes[i] = srgb_byte(sums[i] / counts[i / 3] * scale);
    return encode_png(bytes, w, h, 3);
}

}  // namespace

std::string preview_png(const Image& image, double exposure, uint32_t max_side) {
    return shrunk_png(image.width, image.height, exposure, max_side,
                      [&](size_t i, float v[3]) {
                          for (int c = 0; c < 3; ++c) v[c] = image.rgb[i * 3 + c];
                      });
}

std::string thumbnail_png(const Accumulator& sums, uint32_t max_side) {
    // Each pixel rounded to float as Accumulator::image does: the same bytes as
    // preview_png(sums.image(), 0, max_side).
    return shrunk_png(sums.width(), sums.height(), 0, max_side,
                      [&](size_t i, float v[3]) {
                          double mean[3];
                          sums.mean(i, mean);
                          for (int c = 0; c < 3; ++c) v[c] = float(mean[c]);
                      });
}

json pixel_map(const Image& image, MapKind kind, uint32_t max_side) {
    const Image::Channel* spp = channel(image, kSampleCountChannel);
    const Image::Channel* variance = channel(image, kVarianceChannel);
    if (!spp || !variance)
        throw ApiError(404, "the image has no per-pixel sample counts");
    const uint32_t f = shrink_factor(image.width, image.height, max_side);
    const Plane p = kind == MapKind::Spp
                        ? downsample(image.width, image.height, f,
                                     [&](size_t i) { return double(spp->values[i]); })
                        : downsample(image.width, image.height, f, [&](size_t i) {
                              const double v = variance->values[i];
                              return std::isfinite(v) && v > 0 ? std::sqrt(v) : 0.0;
                          });

    double hi = 0, sum = 0, max = 0;
    for (double v : p.values) {
        sum += v;
        max = std::max(max, v);
    }
    if (kind == MapKind::Spp) {
        hi = max;
    } else {
        // Fireflies would squash a linear scale; clip at the 99th percentile.
        std::vector<double> sorted = p.values;
        const size_t k =
            std::min(sorted.size() - 1, size_t(double(sorted.size()) * 0.99));
        std::nth_element(sorted.begin(), sorted.begin() + ptrdiff_t(k), sorted.end());
        hi = sorted[k];
    }
    if (!(hi > 0)) hi = 1;
    std::string bytes(p.values.size(), '\0');
    for (size_t i = 0; i < p.values.size(); ++i)
        bytes[i] =
            char(uint8_t(std::lround(std::clamp(p.values[i] / hi, 0.0, 1.0) * 255.0)));
    return {{"kind", kind == MapKind::Spp ? "spp" : "error"},
            {"width", p.width},
            {"height", p.height},
            {"image_width", image.width},
            {"image_height", image.height},
            {"lo", 0.0},
            {"hi", hi},
            {"mean", p.values.empty() ? 0.0 : sum / double(p.values.size())},
            {"max", max},
            {"data", base64(bytes)}};
}

double number_param(const std::string& name, const std::string& text, double lo,
                    double hi) {
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || *end != '\0' || !std::isfinite(v) || v < lo || v > hi)
        throw ApiError(400, "'" + name + "' must be a number from " + json(lo).dump() +
                                " to " + json(hi).dump() + ", got \"" + text + "\"");
    return v;
}

std::string base64(const std::string& in) {
    static const char* table =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    out.reserve((in.size() + 2) / 3 * 4);
    size_t i = 0;
    for (; i + 2 < in.size(); i += 3) {
        const uint32_t v = uint32_t(uint8_t(in[i])) << 16 |
                           uint32_t(uint8_t(in[i + 1])) << 8 | uint8_t(in[i + 2]);
        out += table[v >> 18];
        out += table[(v >> 12) & 63];
        out += table[(v >> 6) & 63];
        out += table[v & 63];
    }
    if (i < in.size()) {
        uint32_t v = uint32_t(uint8_t(in[i])) << 16;
        if (i + 1 < in.size()) v |= uint32_t(uint8_t(in[i + 1])) << 8;
        out += table[v >> 18];
        out += table[(v >> 12) & 63];
        out += i + 1 < in.size() ? table[(v >> 6) & 63] : '=';
        out += '=';
    }
    return out;
}

// ---- cross-site requests ----

namespace {

std::string lower(std::string s) {
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

struct HostPort {
    std::string name;  // lower case, IPv6 in brackets, no trailing dot
    int port = -1;     // -1: none given
};

bool valid_name_char(char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' ||
           c == '_';
}

// "name", "name:port", "[v6]", "[v6]:port"; nullopt for anything else.
std::optional<HostPort> split_host(const std::string& text) {
    const std::string h = lower(text);
    HostPort out;
    std::string rest;
    if (!h.empty() && h[0] == '[') {
        const size_t close = h.find(']');
        if (close == std::string::npos) return std::nullopt;
        out.name = h.substr(0, close + 1);
        for (size_t i = 1; i < close; ++i)
            if (!std::isxdigit(static_cast<unsigned char>(h[i])) && h[i] != ':' &&
                h[i] != '.')
                return std::nullopt;
        rest = h.substr(close + 1);
    } else {
        const size_t colon = h.find(':');
        out.name = h.substr(0, colon);
        if (colon != std::string::npos) rest = h.substr(colon);
        if (!out.name.empty() && out.name.back() == '.') out.name.pop_back();
        for (char c : out.name)
            if (!valid_name_char(c)) return std::nullopt;
    }
    if (out.name.empty() || out.name == "[]") return std::nullopt;
    if (!rest.empty()) {
        if (rest[0] != ':' || rest.size() < 2 || rest.size() > 6) return std::nullopt;
        int port = 0;
        for (size_t i = 1; i < rest.size(); ++i) {
            if (!std::isdigit(static_cast<unsigned char>(rest[i]))) return std::nullopt;
            port = port * 10 + (rest[i] - '0');
        }
        if (port > 65535) return std::nullopt;
        out.port = port;
    }
    return out;
}

bool is_ip_literal(const std::string& name) {
    if (name.size() >= 2 && name.front() == '[') {
        in6_addr a6;
        return inet_pton(AF_INET6, name.substr(1, name.size() - 2).c_str(), &a6) == 1;
    }
    in_addr a4;
    return inet_pton(AF_INET, name.c_str(), &a4) == 1;
}

}  // namespace

HostPolicy::HostPolicy(const std::string& listen_host, int port,
                       const std::vector<std::string>& allowed) {
    std::string host = lower(listen_host);
    if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    const bool wildcard = host.empty() || host == "0.0.0.0" || host == "::";
    const bool loopback =
        host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
    if (!wildcard)
        entries_.push_back(
            {host.find(':') != std::string::npos ? "[" + host + "]" : host, port});
    if (wildcard || loopback)
        for (const char* name : {"localhost", "127.0.0.1", "[::1]"})
            entries_.push_back({name, -1});
    any_ip_literal_ = wildcard;
    for (const std::string& entry : allowed) {
        const auto hp = split_host(entry);
        if (!hp || entry.find_first_of("/ \t") != std::string::npos)
            throw std::invalid_argument(
                "allowed host: expected NAME or NAME:PORT, got \"" + entry + "\"");
        entries_.push_back({hp->name, hp->port});
    }
}

bool HostPolicy::allows(const std::string& host_header) const {
    const auto hp = split_host(host_header);
    if (!hp) return false;
    if (any_ip_literal_ && is_ip_literal(hp->name)) return true;
    const int port = hp->port < 0 ? 80 : hp->port;  // no port: HTTP's default
    for (const Entry& e : entries_)
        if (e.name == hp->name && (e.port < 0 || e.port == port)) return true;
    return false;
}

std::string HostPolicy::describe() const {
    // Built with append: GCC 12 warns falsely (-Wrestrict) on "literal" + std::string.
    std::string out;
    for (const Entry& e : entries_) {
        if (!out.empty()) out.append(", ");
        out.append(e.name);
        if (e.port < 0)
            out.append(" (any port)");
        else
            out.append(":").append(std::to_string(e.port));
    }
    if (any_ip_literal_) out.append(out.empty() ? "" : ", ").append("any IP address");
    return out;
}

bool is_json_content_type(const std::string& content_type) {
    std::string type = lower(content_type.substr(0, content_type.find(';')));
    const auto not_space = [](char c) { return c != ' ' && c != '\t'; };
    type.erase(type.begin(), std::find_if(type.begin(), type.end(), not_space));
    type.erase(std::find_if(type.rbegin(), type.rend(), not_space).base(), type.end());
    return type == "application/json";
}

bool origin_matches_host(const std::string& origin, const std::string& host, bool https) {
    const std::string default_port = https ? ":443" : ":80";
    const auto drop_default_port = [&](std::string s) {
        if (s.size() > default_port.size() &&
            s.compare(s.size() - default_port.size(), default_port.size(),
                      default_port) == 0)
            s.resize(s.size() - default_port.size());
        return s;
    };
    if (host.empty()) return false;
    return drop_default_port(lower(origin)) ==
           (https ? "https://" : "http://") + drop_default_port(lower(host));
}

int32_t parse_priority_request(const std::string& body) {
    const json doc = json::parse(body, nullptr, false);
    if (doc.is_discarded() || !doc.is_object() || !doc.contains("priority"))
        throw ApiError(400, "expected a JSON object as the body: {\"priority\": N}");
    for (const auto& [key, v] : doc.items())
        if (key != "priority")
            throw ApiError(400, "unknown field '" + key.substr(0, 64) +
                                    "'; only priority can be changed");
    return priority_number(doc["priority"]);
}

void parse_cancel_request(const std::string& body) {
    const json doc = json::parse(body, nullptr, false);
    if (doc.is_discarded() || !doc.is_object())
        throw ApiError(400, "expected a JSON object as the body: {}");
    if (!doc.empty())
        throw ApiError(400, "unknown field '" + doc.begin().key().substr(0, 64) +
                                "'; cancel takes none");
}

}  // namespace aliquot::http_api
