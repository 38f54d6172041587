#include "merges_in_flight.h"

#include <gtest/gtest.h>

#include <atomic>
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

using Told = std::vector<std::pair<size_t, bool>>;  // a job, and whether it was added

TEST(MergesInFlight, HeldResultsAreAddedInJobOrderWithTheirRefusals) {
    MergesInFlight merges;
    Row row;
    merges.open_round_ahead(4);
    merges.hold(3, result_of(3, 1));
    merges.hold(2, result_of(20));  // outside the row: refused when added
    merges.hold(0, result_of(0, 3));
    Told told;
    const auto tell = [&](size_t job, const std::string& refused) {
        told.push_back({job, refused.empty()});
        return true;
    };
    merges.add_held(row.merged, row.aux, tell);
    EXPECT_EQ(told, (Told{{0, true}, {2, false}, {3, true}}));
    EXPECT_EQ(row.merged.total_samples(), 4u);
    told.clear();
    merges.add_held(row.merged, row.aux, tell);  // added once
    EXPECT_TRUE(told.empty());
}

TEST(MergesInFlight, HeldResultsAreDroppedOnceTheRenderEnds) {
    MergesInFlight merges;
    Row row;
    merges.open_round_ahead(3);
    merges.hold(0, result_of(20));  // refused: its render fails, say
    merges.hold(1, result_of(1));
    Told told;
    merges.add_held(row.merged, row.aux, [&](size_t job, const std::string& refused) {
        told.push_back({job, refused.empty()});
        return false;
    });
    EXPECT_EQ(told, (Told{{0, false}}));
    EXPECT_EQ(row.merged.total_samples(), 0u);
    merges.open_round_ahead(1);
    merges.hold(0, result_of(0));
    merges.drop_held();  // a render cancelled
    merges.add_held(row.merged, row.aux, [&](size_t, const std::string&) {
        ADD_FAILURE() << "a result dropped was added";
        return true;
    });
}

}  // namespace
}  // namespace aliquot
