#include "record_backlog.h"

#include <algorithm>
#include <cstdio>
#include <exception>

namespace aliquot {

namespace {

constexpr std::chrono::milliseconds kFirstDelay{500};
constexpr std::chrono::seconds kLongestDelay{30};

}  // namespace

void RecordBacklog::submit(std::string what, Write write, Clock::time_point now) {
    Pending p{std::move(what), std::move(write)};
    if (!queue_.empty() || !attempt(p, now)) queue_.push_back(std::move(p));
}

void RecordBacklog::retry(Clock::time_point now) {
    if (queue_.empty() || now < next_try_) return;
    while (!queue_.empty()) {
        if (!attempt(queue_.front(), now)) return;
        queue_.pop_front();
    }
}

bool RecordBacklog::attempt(Pending& p, Clock::time_point now) {
    try {
        p.write();
    } catch (const std::exception& e) {
        const bool first = warning_.empty();
        warning_ = "cannot " + p.what + ": " + e.what();
        // Logged when writes start failing and then at most every 30 s, not every retry.
        if (first || delay_ >= kLongestDelay)
            std::fprintf(stderr, "coordinator: %s (kept, retrying)\n", warning_.c_str());
        delay_ = first ? Clock::duration(kFirstDelay)
                       : std::min<Clock::duration>(2 * delay_, kLongestDelay);
        next_try_ = now + delay_;
        return false;
    }
    if (!warning_.empty() && queue_.size() <= 1)
        std::fprintf(stderr, "coordinator: the run record is written again\n");
    if (queue_.size() <= 1) {
        warning_.clear();
        delay_ = {};
    }
    return true;
}

}  // namespace aliquot
