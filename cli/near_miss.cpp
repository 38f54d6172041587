#include "near_miss.h"

#include <algorithm>

namespace aliquot::cli {

namespace {

// Optimal string alignment distance: Levenshtein's plus a swap of two adjacent
// characters as one edit, the commonest typo ("redner").
size_t edit_distance(const std::string& a, const std::string& b) {
    std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
    for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
    for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        for (size_t j = 1; j <= b.size(); ++j) {
            const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            d[i][j] =
                std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
                d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
        }
    }
    return d[a.size()][b.size()];
}

}  // namespace

std::string closest(const std::string& word, const std::vector<std::string>& candidates) {
    // Words on a command line are short; a longer one is no typo of a name.
    if (word.size() > 64) return "";
    std::string best;
    size_t best_distance = 3;  // more than 2 edits is another word, not a typo
    for (const std::string& c : candidates) {
        const size_t d = edit_distance(word, c);
        if (d < best_distance && 2 * d < c.size()) {
            best = c;
            best_distance = d;
        }
    }
    return best;
}

}  // namespace aliquot::cli
