// Every strategy parameter declared once: its key, default, bounds, help and the methods
// that read it. The value lives in a StrategyParams member (so strategies read plain
// fields); this table points at that member. JSON (to_json, from_json), validate(), the
// CLI's flags (cli/render_options.cpp), GET /api/methods and the dashboard's form (which
// reads that) are all made from it, so a parameter added here appears everywhere at once.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "json_field.h"
#include "strategy_params.h"

namespace aliquot {

struct StrategyParameter {
    using Member = std::variant<uint64_t StrategyParams::*, uint32_t StrategyParams::*,
                                double StrategyParams::*, std::string StrategyParams::*>;
    enum class Kind { Whole, Number, Word };

    std::string key;  // the JSON key; the CLI's flag is --key with '-' for '_'
    Member member;
    // Whole and Number: the values allowed, [min, max], an end left out when open
    // (Number only: an infinite max is no bound). Whole bounds stay below 2^53, exact.
    double min = 0, max = 0;
    bool min_open = false, max_open = false;
    std::vector<std::string> words;  // Word: the values allowed
    std::string help;
    std::vector<std::string> methods;  // the methods that read it

    Kind kind() const;
    bool applies_to(std::string_view method) const;
    std::string flag() const;  // "--sigma-radius"
    // What the bounds allow, as words: "a whole number from 0 to 64", "a number at
    // least 0 and below 1", "seed or paper".
    std::string bounds() const;
    // The value held in `p`: a JSON number or string.
    nlohmann::json get(const StrategyParams& p) const;
    nlohmann::json default_value() const { return get(StrategyParams{}); }
    // Stores `v` in `p`; a value of the wrong type or out of bounds fails at `v`
    // (JsonError) with "expected " + bounds().
    void read(const JsonField& v, StrategyParams& p) const;
    // "" when `p`'s value is within bounds, else "must be BOUNDS, got VALUE".
    std::string out_of_bounds(const StrategyParams& p) const;
};

// In the order --help and the dashboard show them: the budget and caps every method
// reads, then each method's own.
const std::vector<StrategyParameter>& strategy_parameters();
// nullptr for a key that is no parameter ("method" is none: it chooses the others).
const StrategyParameter* find_strategy_parameter(std::string_view key);

// A method in a sentence, for --help, GET /api/methods and the dashboard.
const std::string& method_summary(const std::string& method);

// GET /api/methods: every method (submittable or not: an oracle render's page needs its
// parameters too) with its summary and its parameters' keys, kinds, defaults, bounds
// and help.
nlohmann::json methods_json();

}  // namespace aliquot
