#include "round_end_stats.h"

#include <ctime>

#include "bands.h"

namespace aliquot {

namespace {

// The band pool's threads work for the round end too (bands.h): their CPU time counts.
// Another render's round end running meanwhile would be counted here as well;
// farm_scale runs one render.
double cpu_seconds_now() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec) + band_pool_cpu_seconds();
}

}  // namespace

RoundEndMeter::RoundEndMeter(const RenderSession& session)
    : rounds_before_(session.rounds_done()),
      began_(std::chrono::steady_clock::now()),
      began_cpu_(cpu_seconds_now()) {}

RoundEnd RoundEndMeter::finish(const RenderSession& session) const {
    // The result ended a round, or two: the round after it, opened ahead, may have
    // merged whole by then.
    if (session.rounds_done() == rounds_before_) return {};
    RoundEnd end;
    end.rounds = session.rounds_done() - rounds_before_;
    end.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - began_).count();
    end.cpu_seconds = cpu_seconds_now() - began_cpu_;
    end.waited =
        !(session.state() == RenderState::Running && session.round_opened_ahead());
    return end;
}

void RoundEndStats::add(const RoundEnd& end) {
    if (end.rounds == 0) return;
    std::lock_guard lock(mutex_);
    totals_.seconds += end.seconds;
    totals_.cpu_seconds += end.cpu_seconds;
    if (end.waited) totals_.wait_seconds += end.seconds;
    totals_.rounds += end.rounds;
}

RoundEndStats::Totals RoundEndStats::totals() const {
    std::lock_guard lock(mutex_);
    return totals_;
}

}  // namespace aliquot
