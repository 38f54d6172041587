// Fuzzes the body of POST /api/renders and the spec check Coordinator::submit runs on it
// first. Their contract: a RenderSpec or an ApiError (the server answers its status),
// then a valid spec or std::invalid_argument (answered 400).
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
    return 0;
}
