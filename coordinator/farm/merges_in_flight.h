// MergesInFlight: one render's results between the end of their lease and the count of
// their merge (RenderSession::begin_merge to end_merge). A result of the round out adds
// its sums off the render's lock: this records which adds are in flight, lets what reads
// the buffers' pixels wait for them, and names those refused, whose jobs are unmerged
// until their end_merge puts them back. A result of the round ahead is held here until
// the round out has ended (docs/FARM.md, "Locks").
//
// Called under the render's lock, but for end_add, which an add calls off it, and the
// waits; the adds' own mutex is taken after the render's lock, never before it.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "accumulator.h"
#include "aux_sums.h"
#include "lease.h"
#include "sample_job.h"

namespace aliquot {

class MergesInFlight {
public:
    // One result's merge, from begin_merge to end_merge.
    struct Merge {
        // Set: decided in begin_merge (ignored, rejected or held); add and end nothing.
        std::optional<CompleteOutcome> outcome;
        ResultTotals totals;  // what the result adds (when merged or held)
        size_t job = 0;
        const uint32_t* counts = nullptr;  // the job's, stable while it merges
        std::string refused;               // add's reason, when it refused
        bool added = false;
        bool held =
            false;  // of the round ahead: merged, or refused, at its round's start
    };
    // Whom a held result's samples count for once it merges (the coordinator's merged
    // samples and its worker's): a result held and then refused counts for no one.
    struct Credit {
        std::string worker;
        uint64_t samples = 0;
        double wall_seconds = 0;
    };

    // The add of job `job` begins: it is in flight until counted. Called before the job's
    // lease ends, so that a failure here (no memory) leaves the job leased, not lost.
    void begin_add(size_t job);
    // Off the render's lock: checks `result` against its job and the buffers, then adds
    // it, or refuses it whole; the add is then over, the job unmerged until counted when
    // refused. Never throws: an add that never ended would hold up every wait for adds
    // for good (a cancel, an image, the tick behind them). `while_adding` (tests) is
    // called between the check and the add.
    void add(Merge& merge, const SampleJobResult& result, Accumulator& merged,
             AuxSums& aux, const std::function<void(size_t job)>& while_adding);
    // Under the render's lock again: `job`'s merge is counted (or its refusal, the job
    // back in its queue), and no longer in flight.
    void count(size_t job);
    // Waits until every add in flight is over: the buffers' pixels are then what the
    // merges counted so far, and the refused, made them.
    void wait_for_adds() const;
    // Jobs whose add was refused and whose refusal is not counted yet.
    std::vector<size_t> refused() const;

    // The round ahead opens with `jobs` jobs: a place for each one's held result, made
    // now, so that holding one cannot fail once its lease has ended.
    void open_round_ahead(size_t jobs);
    // Holds the result of the round ahead's job `place` (its index in that round) until
    // that round is the one out.
    void hold(size_t place, SampleJobResult&& result, Credit&& credit) noexcept;
    // How a held result's add ended: added, refused (MergeError: the result's fault,
    // counted against its worker), or not made (anything else, such as no memory: the
    // coordinator's, its job to be traced again).
    enum class HeldEnd { Added, Refused, NotAdded };
    // The round ahead is now the round out: its held results are added to `merged` and
    // `aux`, in job order, and `ended` told of each (its job's index in the round, how,
    // why when not added, and its credit), while it returns true; the rest are dropped (a
    // render that failed on one). Every held result reaches `ended`, whatever its add
    // threw; `ended` must not throw, or the results after it would be lost.
    // `while_adding` (tests) is called between each one's check and its add.
    void add_held(
        Accumulator& merged, AuxSums& aux,
        const std::function<void(size_t job)>& while_adding,
        const std::function<bool(size_t job, HeldEnd how, const std::string& why,
                                 const Credit& credit)>& ended);
    // The render has ended: what was held will never merge.
    void drop_held() noexcept;

private:
    // Checks `result`, calls `while_adding`, adds it; how that ended, and why if not
    // added. Never throws.
    static HeldEnd add_one(Accumulator& merged, AuxSums& aux,
                           const SampleJobResult& result, const uint32_t* counts,
                           size_t job,
                           const std::function<void(size_t job)>& while_adding,
                           ResultTotals& totals, std::string& why) noexcept;
    // `job`'s add is over, its sums added or the result refused.
    void end_add(size_t job, bool added);

    struct Add {
        size_t job;
        bool over = false, refused = false;
    };
    mutable std::mutex mutex_;
    mutable std::condition_variable over_;
    std::vector<Add> adds_;
    struct Held {
        SampleJobResult result;
        Credit credit;
    };
    std::vector<std::optional<Held>> held_;  // the round ahead's, by place
};

}  // namespace aliquot
