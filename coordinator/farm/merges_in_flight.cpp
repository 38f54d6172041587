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
    // Refused, whole, a result unlike its job or sums that would stop being finite; and
    // one whose add failed otherwise (no memory for a reason, a test's hook) too.
    merge.added = add_one(merged, aux, result, merge.counts, merge.job, while_adding,
                          merge.totals, merge.refused) == HeldEnd::Added;
    end_add(merge.job, merge.added);
}

MergesInFlight::HeldEnd MergesInFlight::add_one(
    Accumulator& merged, AuxSums& aux, const SampleJobResult& result,
    const uint32_t* counts, size_t job,
    const std::function<void(size_t job)>& while_adding, ResultTotals& totals,
    std::string& why) noexcept {
    // Each reason short of memory falls back to one std::string holds in itself (15
    // characters), which takes none.
    try {
        totals = check_with_aux(merged, aux, result, counts);
        if (while_adding) while_adding(job);
        add_with_aux(merged, aux, result, totals);
        return HeldEnd::Added;
    } catch (const MergeError& e) {
        try {
            why = e.what();
        } catch (...) {
            why = "refused";
        }
        return HeldEnd::Refused;
    } catch (const std::exception& e) {
        try {
            why = e.what();
        } catch (...) {
            why = "out of memory";
        }
    } catch (...) {
        why = "unknown error";
    }
    return HeldEnd::NotAdded;
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

void MergesInFlight::hold(size_t place, SampleJobResult&& result,
                          Credit&& credit) noexcept {
    held_[place] = Held{std::move(result), std::move(credit)};
}

void MergesInFlight::add_held(
    Accumulator& merged, AuxSums& aux,
    const std::function<void(size_t job)>& while_adding,
    const std::function<bool(size_t job, HeldEnd how, const std::string& why,
                             const Credit& credit)>& ended) {
    std::vector<std::optional<Held>> held = std::exchange(held_, {});
    for (size_t j = 0; j < held.size(); ++j) {
        if (!held[j]) continue;
        // Checked as asked when it came; its sums against the buffers now (no counts).
        ResultTotals totals;
        std::string why;
        const HeldEnd how =
            add_one(merged, aux, held[j]->result, nullptr, j, while_adding, totals, why);
        const bool go_on = ended(j, how, why, held[j]->credit);
        held[j].reset();
        if (!go_on) return;
    }
}

void MergesInFlight::drop_held() noexcept { held_.clear(); }

}  // namespace aliquot
