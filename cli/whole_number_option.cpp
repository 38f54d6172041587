#include "whole_number_option.h"

#include <string>

namespace aliquot::cli {

namespace {

bool is_plain_decimal(const std::string& text) {
    if (text.empty() || text.size() > 20) return false;
    for (const char c : text)
        if (c < '0' || c > '9') return false;
    if (text.size() > 1 && text[0] == '0') return false;  // strtoull reads it as octal
    // Twenty digits of the same length compare as numbers do.
    return text.size() < 20 || text <= "18446744073709551615";
}

}  // namespace

const CLI::Validator& whole_number() {
    static const CLI::Validator validator(
        [](std::string& text) -> std::string {
            if (is_plain_decimal(text)) return "";
            return "expected a whole number in decimal digits (no sign, no leading zero, "
                   "at most 18446744073709551615), got '" +
                   text + "'";
        },
        "DIGITS");
    return validator;
}

const CLI::Validator& signed_whole_number() {
    static const CLI::Validator validator(
        [](std::string& text) -> std::string {
            const std::string digits =
                !text.empty() && text[0] == '-' ? text.substr(1) : text;
            if (is_plain_decimal(digits) && digits.size() <= 10) return "";
            return "expected a whole number in decimal digits, optionally negative, got "
                   "'" +
                   text + "'";
        },
        "INTEGER");
    return validator;
}

}  // namespace aliquot::cli
