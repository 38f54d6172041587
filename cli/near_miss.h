// "Did you mean …?": the known word closest to one the user mistyped (`aliquot rendr`,
// `--spd`), so that a usage error points at the fix rather than only at the mistake.
#pragma once

#include <string>
#include <vector>

namespace aliquot::cli {

// The candidate nearest to `word` by edit distance (insertions, deletions, substitutions
// and swaps of two neighbours), or "" when none is near enough to be a typo: at most 2
// edits, and fewer than half of the candidate's length.
std::string closest(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace aliquot::cli
