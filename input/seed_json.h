// Render seeds in JSON. A seed is any uint64, and JSON numbers pass through doubles in
// JavaScript (the dashboard) and many parsers, which keep 53 bits: so every document
// writes a seed as a decimal string, as protobuf's JSON mapping does for 64-bit integers,
// and reads a string or a number (a number written as an integer is exact here; one with
// a fraction or exponent is a double, trusted up to 2^53 only).
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace aliquot {

// "12345678901234567890".
nlohmann::json seed_to_json(uint64_t seed);

// Throws std::invalid_argument saying what a seed must be (the caller names the field).
uint64_t seed_from_json(const nlohmann::json& value);

// Doubles hold every whole number up to here exactly.
constexpr uint64_t kExactDoubleLimit = uint64_t(1) << 53;

}  // namespace aliquot
