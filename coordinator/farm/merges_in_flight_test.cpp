#include "merges_in_flight.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace aliquot {
namespace {

SampleJobResult result_of(uint32_t x) {
    SampleJobResult result;
    result.rect = {x, 0, 1, 1};
    result.pixels.resize(1);
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
        SampleJobResult result = result_of(uint32_t(merge.job));
        result.pixels[0].samples = samples;
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

TEST(MergesInFlight, HeldResultsComeBackByTheirPlaceInTheRoundAhead) {
    MergesInFlight merges;
    merges.open_round_ahead(4);
    merges.hold(2, result_of(20));
    merges.hold(0, result_of(0));
    const std::vector<std::optional<SampleJobResult>> held = merges.take_held();
    ASSERT_EQ(held.size(), 4u);
    ASSERT_TRUE(held[0] && held[2]);
    EXPECT_FALSE(held[1] || held[3]);
    EXPECT_EQ(held[0]->rect.x, 0u);
    EXPECT_EQ(held[2]->rect.x, 20u);
    EXPECT_TRUE(merges.take_held().empty());  // taken once
}

TEST(MergesInFlight, ARenderThatEndsDropsWhatItHeld) {
    MergesInFlight merges;
    merges.open_round_ahead(2);
    merges.hold(1, result_of(1));
    merges.drop_held();
    EXPECT_TRUE(merges.take_held().empty());
}

}  // namespace
}  // namespace aliquot
