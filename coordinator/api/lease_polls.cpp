#include "lease_polls.h"

namespace aliquot {

LeasePolls::Place::Place(LeasePolls& polls, const std::string& session)
    : polls_(polls), session_(session) {
    std::lock_guard lock(polls_.mutex_);
    if (polls_.total_ >= polls_.max_total_) return;
    const auto it = polls_.per_session_.try_emplace(session_, 0).first;
    if (it->second >= polls_.max_per_session_) {
        if (it->second == 0) polls_.per_session_.erase(it);
        return;
    }
    ++it->second;
    ++polls_.total_;
    taken_ = true;
}

LeasePolls::Place::~Place() {
    if (!taken_) return;
    std::lock_guard lock(polls_.mutex_);
    --polls_.total_;
    const auto it = polls_.per_session_.find(session_);
    if (--it->second == 0) polls_.per_session_.erase(it);
}

int LeasePolls::waiting() {
    std::lock_guard lock(mutex_);
    return total_;
}

}  // namespace aliquot
