#include "merges_in_flight.h"

#include <gtest/gtest.h>

#include <atomic>
#include <new>
#include <thread>
#include <utility>

namespace aliquot {
namespace {

// Pixel x's result: `samples` samples of zero radiance.
SampleJobResult result_of(uint32_t x, uint32_t samples = 1) {
    SampleJobResult result;
    result.rect = {x, 0, 1, 1};
    result.pixels.resize(1);
    result.pixels[0].samples = samples;
    return result;
}

const uint32_t kOneSample = 1;

// Pixel x of a row of 8 merges as job x, one sample asked of it.
struct Row {
    Accumulator merged{8, 1};
    AuxSums aux;  // no first hits kept

    MergesInFlight::Merge begin(MergesInFlight& merges, size_t x) {
        merges.begin_add(x);
        MergesInFlight::Merge merge;
        merge.job = x;
        merge.counts = &kOneSample;
        return merge;
    }
    // Adds pixel x's result: with `samples` unlike the one asked, it is refused.
    void add(MergesInFlight& merges, MergesInFlight::Merge& merge, uint32_t samples = 1) {
        const SampleJobResult result = result_of(uint32_t(merge.job), samples);
        merges.add(merge, result, merged, aux, {});
    }
};

TEST(MergesInFlight, AWaitForAddsEndsWhenEveryAddInFlightIsOver) {
    MergesInFlight merges;
    Row row;
    merges.wait_for_adds();  // none in flight
    MergesInFlight::Merge three = row.begin(merges, 3), five = row.begin(merges, 5);
    std::atomic<bool> waited{false};
    std::thread reader([&] {
        merges.wait_for_adds();
        waited = true;
    });
    row.add(merges, three);
    EXPECT_TRUE(three.added);
    // One add is still in flight: the reader cannot have passed (no time is waited on:
    // a reader that passed too early is seen whenever it runs before the next line).
    EXPECT_FALSE(waited);
    row.add(merges, five);
    reader.join();
    EXPECT_TRUE(waited);
    merges.count(3);
    merges.count(5);
    merges.wait_for_adds();
}

TEST(MergesInFlight, ARefusedAddNamesItsJobUntilItsRefusalIsCounted) {
    MergesInFlight merges;
    Row row;
    MergesInFlight::Merge two = row.begin(merges, 2), seven = row.begin(merges, 7);
    EXPECT_TRUE(merges.refused().empty());  // in flight, not refused yet
    row.add(merges, two, 2);                // unlike its job
    row.add(merges, seven);
    EXPECT_FALSE(two.added);
    EXPECT_FALSE(two.refused.empty());
    EXPECT_EQ(row.merged.total_samples(), 1u);  // seven's alone
    EXPECT_EQ(merges.refused(), std::vector<size_t>{2});
    merges.wait_for_adds();  // a refused add is over too
    merges.count(2);         // its job back in its queue
    EXPECT_TRUE(merges.refused().empty());
    merges.count(7);
}

using HeldEnd = MergesInFlight::HeldEnd;
using Told = std::vector<std::pair<size_t, HeldEnd>>;  // a job, and how its add ended

TEST(MergesInFlight, HeldResultsAreAddedInJobOrderWithTheirRefusals) {
    MergesInFlight merges;
    Row row;
    merges.open_round_ahead(4);
    merges.hold(3, result_of(3, 1), {"w", 1, 0.5});  // counted for "w" once added
    merges.hold(2, result_of(20), {});  // outside the row: refused when added
    merges.hold(0, result_of(0, 3), {});
    Told told;
    const auto tell = [&](size_t job, HeldEnd how, const std::string& why,
                          const MergesInFlight::Credit& credit) {
        EXPECT_EQ(why.empty(), how == HeldEnd::Added) << job;
        EXPECT_EQ(credit.worker, job == 3 ? "w" : "") << job;
        told.push_back({job, how});
        return true;
    };
    merges.add_held(row.merged, row.aux, {}, tell);
    EXPECT_EQ(told,
              (Told{{0, HeldEnd::Added}, {2, HeldEnd::Refused}, {3, HeldEnd::Added}}));
    EXPECT_EQ(row.merged.total_samples(), 4u);
    told.clear();
    merges.add_held(row.merged, row.aux, {}, tell);  // added once
    EXPECT_TRUE(told.empty());
}

// An add that throws anything but a refusal (no memory; here a test's hook) is told as
// not added, and the held results after it are still added: none is lost with it.
TEST(MergesInFlight, AHeldAddThatFailsLosesNoneAfterIt) {
    MergesInFlight merges;
    Row row;
    merges.open_round_ahead(3);
    for (uint32_t j = 0; j < 3; ++j) merges.hold(j, result_of(j, 1), {});
    Told told;
    merges.add_held(
        row.merged, row.aux,
        [](size_t job) {
            if (job == 1) throw std::bad_alloc();
        },
        [&](size_t job, HeldEnd how, const std::string& why,
            const MergesInFlight::Credit&) {
            EXPECT_EQ(why.empty(), how == HeldEnd::Added) << job;
            told.push_back({job, how});
            return true;
        });
    EXPECT_EQ(told,
              (Told{{0, HeldEnd::Added}, {1, HeldEnd::NotAdded}, {2, HeldEnd::Added}}));
    EXPECT_EQ(row.merged.total_samples(), 2u);
}

TEST(MergesInFlight, HeldResultsAreDroppedOnceTheRenderEnds) {
    MergesInFlight merges;
    Row row;
    merges.open_round_ahead(3);
    merges.hold(0, result_of(20), {});  // refused: its render fails, say
    merges.hold(1, result_of(1), {});
    Told told;
    merges.add_held(
        row.merged, row.aux, {},
        [&](size_t job, HeldEnd how, const std::string&, const MergesInFlight::Credit&) {
            told.push_back({job, how});
            return false;
        });
    EXPECT_EQ(told, (Told{{0, HeldEnd::Refused}}));
    EXPECT_EQ(row.merged.total_samples(), 0u);
    merges.open_round_ahead(1);
    merges.hold(0, result_of(0), {});
    merges.drop_held();  // a render cancelled
    merges.add_held(
        row.merged, row.aux, {},
        [&](size_t, HeldEnd, const std::string&, const MergesInFlight::Credit&) {
            ADD_FAILURE() << "a result dropped was added";
            return true;
        });
}

}  // namespace
}  // namespace aliquot
