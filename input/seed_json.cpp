#include "seed_json.h"

#include <cmath>
#include <stdexcept>

namespace aliquot {

namespace {

const char* const kWhatASeedIs =
    "a seed is a whole number from 0 to 18446744073709551615, as a decimal string "
    "(\"42\") or a number";

uint64_t from_decimal(const std::string& text) {
    if (text.empty() || text.size() > 20) throw std::invalid_argument(kWhatASeedIs);
    uint64_t value = 0;
    for (const char c : text) {
        if (c < '0' || c > '9') throw std::invalid_argument(kWhatASeedIs);
        const uint64_t digit = uint64_t(c - '0');
        if (value > (UINT64_MAX - digit) / 10) throw std::invalid_argument(kWhatASeedIs);
        value = value * 10 + digit;
    }
    return value;
}

}  // namespace

nlohmann::json seed_to_json(uint64_t seed) { return std::to_string(seed); }

uint64_t seed_from_json(const nlohmann::json& v) {
    if (v.is_string()) return from_decimal(v.get<std::string>());
    if (v.is_number_unsigned()) return v.get<uint64_t>();
    if (v.is_number_integer() && v.get<int64_t>() >= 0) return uint64_t(v.get<int64_t>());
    if (v.is_number_float()) {
        const double d = v.get<double>();
        if (d >= 0 && d == std::floor(d) && d <= double(kExactDoubleLimit))
            return uint64_t(d);
        if (d == std::floor(d) && d > double(kExactDoubleLimit))
            throw std::invalid_argument(
                "a seed above 2^53 written as a floating-point number has lost its last "
                "digits; send it as a decimal string");
    }
    throw std::invalid_argument(kWhatASeedIs);
}

}  // namespace aliquot
