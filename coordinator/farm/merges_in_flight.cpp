#include "merges_in_flight.h"

#include <algorithm>
#include <utility>

namespace aliquot {

void MergesInFlight::begin_add(size_t job) {
    std::lock_guard lock(mutex_);
    adds_.push_back({job});
}

void MergesInFlight::add(Merge& merge, const SampleJobResult& result, Accumulator& merged,
                         AuxSums& aux,
                         const std::function<void(size_t job)>& while_adding) {
    try {
        // Refuses, whole, a result unlike its job or sums that would stop being finite.
        merge.totals = check_with_aux(merged, aux, result, merge.counts);
        if (while_adding) while_adding(merge.job);
        add_with_aux(merged, aux, result, merge.totals);
        merge.added = true;
    } catch (...) {
        // MergeError's reason; anything else refuses the result too (no memory left for
        // a reason, a test's hook).
        try {
            throw;
        } catch (const std::exception& e) {
            try {
                merge.refused = e.what();
            } catch (...) {
            }
        } catch (...) {
        }
    }
    end_add(merge.job, merge.added);
}

void MergesInFlight::end_add(size_t job, bool added) {
    {
        std::lock_guard lock(mutex_);
        for (Add& a : adds_)
            if (a.job == job) {
                a.over = true;
                a.refused = !added;
            }
    }
    over_.notify_all();
}

void MergesInFlight::count(size_t job) {
    std::lock_guard lock(mutex_);
    const auto it = std::find_if(adds_.begin(), adds_.end(),
                                 [&](const Add& a) { return a.job == job; });
    if (it != adds_.end()) adds_.erase(it);
}

void MergesInFlight::wait_for_adds() const {
    std::unique_lock lock(mutex_);
    over_.wait(lock, [&] {
        return std::all_of(adds_.begin(), adds_.end(),
                           [](const Add& a) { return a.over; });
    });
}

std::vector<size_t> MergesInFlight::refused() const {
    std::vector<size_t> out;
    std::lock_guard lock(mutex_);
    for (const Add& a : adds_)
        if (a.refused) out.push_back(a.job);
    return out;
}

void MergesInFlight::open_round_ahead(size_t jobs) {
    held_.clear();
    held_.resize(jobs);
}

void MergesInFlight::hold(size_t place, SampleJobResult&& result) noexcept {
    held_[place] = std::move(result);
}

void MergesInFlight::add_held(
    Accumulator& merged, AuxSums& aux,
    const std::function<bool(size_t job, const std::string& refused)>& added) {
    std::vector<std::optional<SampleJobResult>> held = std::exchange(held_, {});
    for (size_t j = 0; j < held.size(); ++j) {
        if (!held[j]) continue;
        std::string refused;  // checked when it came; the add may still refuse it
        try {
            merge_with_aux(merged, aux, *held[j]);
        } catch (const MergeError& e) {
            refused = e.what();
        }
        held[j].reset();
        if (!added(j, refused)) return;
    }
}

void MergesInFlight::drop_held() noexcept { held_.clear(); }

}  // namespace aliquot
