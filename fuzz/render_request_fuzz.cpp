// Fuzzes the body of POST /api/renders and the spec check Coordinator::submit runs on it
// first, and the bodies of PATCH /api/renders/{id} and of cancel. Their contract: a
// RenderSpec (a priority) or an ApiError (the server answers its status), then a valid
// spec or std::invalid_argument (answered 400).
#include <cstddef>
#include <cstdint>
#include <string>

#include <stdexcept>

#include "http_api.h"
#include "render_spec.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string body(reinterpret_cast<const char*>(data), size);
    try {
        const aliquot::RenderSpec spec = aliquot::http_api::parse_render_request(body);
        aliquot::validate(spec);
    } catch (const aliquot::http_api::ApiError&) {
    } catch (const std::invalid_argument&) {
    }
    try {
        aliquot::http_api::parse_priority_request(body);
    } catch (const aliquot::http_api::ApiError&) {
    }
    try {
        aliquot::http_api::parse_cancel_request(body);
    } catch (const aliquot::http_api::ApiError&) {
    }
    return 0;
}
