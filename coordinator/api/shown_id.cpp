#include "shown_id.h"

namespace aliquot {

std::string shown_id(std::string_view id) {
    constexpr size_t kMaxShown = 64;
    std::string out;
    for (const char c : id.substr(0, kMaxShown)) out += c >= 0x20 && c < 0x7f ? c : '?';
    if (id.size() > kMaxShown) out += "... (" + std::to_string(id.size()) + " bytes)";
    return out;
}

}  // namespace aliquot
