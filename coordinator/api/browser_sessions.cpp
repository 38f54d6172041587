#include "browser_sessions.h"

#include <algorithm>

#include "secret.h"

namespace aliquot {

namespace {

constexpr size_t kSelectorDigits = 32;  // and as many for the verifier

}  // namespace

BrowserSessions::BrowserSessions(SessionLimits limits, Clock clock)
    : limits_(limits), clock_(std::move(clock)) {}

bool BrowserSessions::expired(const Session& s,
                              std::chrono::steady_clock::time_point now) const {
    return now - s.used >= limits_.idle || now - s.opened >= limits_.lifetime;
}

std::string BrowserSessions::open() {
    const std::string id = random_hex(kSelectorDigits);  // bytes: twice as many digits
    const auto now = clock_();
    std::lock_guard lock(mutex_);
    std::erase_if(sessions_,
                  [&](const auto& entry) { return expired(entry.second, now); });
    if (limits_.max_sessions == 0) return id;  // a session that opens nothing
    if (sessions_.size() >= limits_.max_sessions) {
        const auto least = std::min_element(
            sessions_.begin(), sessions_.end(),
            [](const auto& a, const auto& b) { return a.second.used < b.second.used; });
        sessions_.erase(least);
    }
    sessions_[id.substr(0, kSelectorDigits)] = {id.substr(kSelectorDigits), now, now};
    return id;
}

bool BrowserSessions::use(std::string_view id) {
    if (id.size() != 2 * kSelectorDigits) return false;
    const auto now = clock_();
    std::lock_guard lock(mutex_);
    const auto it = sessions_.find(id.substr(0, kSelectorDigits));
    if (it == sessions_.end() ||
        !constant_time_equal(it->second.verifier, id.substr(kSelectorDigits)))
        return false;
    if (expired(it->second, now)) {
        sessions_.erase(it);
        return false;
    }
    it->second.used = now;
    return true;
}

void BrowserSessions::close(std::string_view id) {
    if (id.size() != 2 * kSelectorDigits) return;
    std::lock_guard lock(mutex_);
    const auto it = sessions_.find(id.substr(0, kSelectorDigits));
    if (it != sessions_.end() &&
        constant_time_equal(it->second.verifier, id.substr(kSelectorDigits)))
        sessions_.erase(it);
}

size_t BrowserSessions::size() const {
    std::lock_guard lock(mutex_);
    return sessions_.size();
}

}  // namespace aliquot
