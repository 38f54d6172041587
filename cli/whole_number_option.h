// Integer options as people write them. CLI11 converts integers with strtoull / strtoll
// in base 0, so "010" was 8, "0x10" 16, "-1" the largest uint64 and an overflow the
// largest value, all without a word: `--seed -1` rendered seed 18446744073709551615.
#pragma once

#include <CLI/CLI.hpp>

namespace aliquot::cli {

// Checks an integer option's text before CLI11 converts it: decimal digits only, no sign,
// no leading zero, at most 18446744073709551615 (an option of a smaller type refuses
// more, with CLI11's own message). A refusal is a usage error, exit status 2.
const CLI::Validator& whole_number();
// The same with an optional minus sign, for signed options (a priority); the option's
// type refuses what it cannot hold.
const CLI::Validator& signed_whole_number();

}  // namespace aliquot::cli
