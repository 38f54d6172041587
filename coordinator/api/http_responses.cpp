// The HTTP server's ways of answering (http_responses.h).
#include "http_responses.h"

#include <algorithm>
#include <fstream>
#include <memory>
#include <vector>

#include "http_api.h"
#include "http_front.h"
#include "shown_id.h"

namespace aliquot {

using http_api::ApiError;
using nlohmann::json;

std::string json_text(const json& body) {
    return body.dump(-1, ' ', false, json::error_handler_t::replace);
}

void send_json(httplib::Response& res, const json& body, int status) {
    res.status = status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(json_text(body), "application/json");
}

std::string quoted_id(const std::string& id) { return "'" + shown_id(id) + "'"; }

void send_error(httplib::Response& res, int status, const std::string& message) {
    send_json(res, {{"error", message}}, status);
}

void send_image(httplib::Response& res, std::string body, const std::string& type,
                Admission::Place place) {
    HttpFront::pace_current_response(body.size());
    if (body.empty()) return res.set_content("", type);
    auto held = std::make_shared<const std::string>(std::move(body));
    res.set_content_provider(
        held->size(), type,
        [held, place](size_t offset, size_t length, httplib::DataSink& sink) {
            return offset <= held->size() &&
                   sink.write(held->data() + offset,
                              std::min(length, held->size() - offset));
        });
}

void send_file(httplib::Response& res, const std::filesystem::path& path,
               const std::string& type, Admission::Place place) {
    constexpr size_t kChunk = 1 << 20;
    auto in = std::make_shared<std::ifstream>(path, std::ios::binary | std::ios::ate);
    if (!*in) throw ApiError(404, "no file " + path.filename().string());
    const auto size = size_t(in->tellg());
    HttpFront::pace_current_response(size);
    if (size == 0) return res.set_content("", type);
    auto buffer = std::make_shared<std::vector<char>>(std::min(size, kChunk));
    res.set_content_provider(
        size, type,
        [in, buffer, place](size_t offset, size_t length, httplib::DataSink& sink) {
            // Nothing may throw out of a provider: it runs on a server thread, outside
            // any handler's try. A read that falls short cuts the response.
            try {
                const size_t n = std::min(length, buffer->size());
                in->seekg(std::streamoff(offset));
                in->read(buffer->data(), std::streamsize(n));
                if (size_t(in->gcount()) != n) return false;
                return sink.write(buffer->data(), n);
            } catch (...) {
                return false;
            }
        });
}

}  // namespace aliquot
