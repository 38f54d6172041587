// A result's sums read where a message holds them, and what makes them its own.
#include "sums_array.h"

#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "sample_job.h"

namespace aliquot {
namespace {

std::vector<PixelSums> three_pixels() {
    std::vector<PixelSums> sums(3);
    for (size_t i = 0; i < sums.size(); ++i) {
        sums[i].samples = i + 1;
        sums[i].even[0] = 0.5 * double(i);
    }
    return sums;
}

TEST(SumsArray, ABorrowedArrayIsReadWhereItsSumsAre) {
    const std::vector<PixelSums> message = three_pixels();
    SumsArray<PixelSums> sums;
    sums.borrow(message.data(), message.size());
    const SumsArray<PixelSums>& read = sums;
    EXPECT_TRUE(read.borrows());
    EXPECT_EQ(read.data(), message.data());
    EXPECT_EQ(read.size(), 3u);
    EXPECT_EQ(read[2].samples, 3u);
}

// What outlives the message owns its sums: a copy, a move, a change. The message is
// scribbled over after each, and what was made still reads the sums it had.
TEST(SumsArray, ACopyAMoveOrAChangeOfABorrowedArrayOwnsItsSums) {
    std::vector<PixelSums> message = three_pixels();
    SumsArray<PixelSums> to_move;
    to_move.borrow(message.data(), message.size());
    const SumsArray<PixelSums> moved = std::move(to_move);
    SumsArray<PixelSums> source;
    source.borrow(message.data(), message.size());
    const SumsArray<PixelSums> copied = source;
    SumsArray<PixelSums> assigned;
    assigned = std::move(source);
    SumsArray<PixelSums> changed;
    changed.borrow(message.data(), message.size());
    changed[0].rays = 7;
    const std::vector<const SumsArray<PixelSums>*> made = {&moved, &copied, &assigned,
                                                           &changed};
    for (const SumsArray<PixelSums>* sums : made) EXPECT_FALSE(sums->borrows());
    for (PixelSums& p : message) p.samples = 99;
    for (const SumsArray<PixelSums>* sums : made) {
        ASSERT_EQ(sums->size(), 3u);
        for (size_t i = 0; i < 3; ++i) EXPECT_EQ((*sums)[i].samples, i + 1);
    }
    EXPECT_EQ(changed[0].rays, 7u);
    EXPECT_EQ(message[0].rays, 0u);
}

// An owned array moves its buffer: no copy, nothing allocated.
TEST(SumsArray, AnOwnedArrayMovesItsBuffer) {
    SumsArray<PixelSums> owned;
    owned.assign(3, PixelSums{});
    const PixelSums* buffer = owned.data();
    const SumsArray<PixelSums> moved = std::move(owned);
    EXPECT_EQ(moved.data(), buffer);
}

TEST(SumsArray, ResultsWithTheSameSumsAreEqualHoweverHeld) {
    const std::vector<PixelSums> message = three_pixels();
    SumsArray<PixelSums> borrowed, owned;
    borrowed.borrow(message.data(), message.size());
    owned.assign(message.begin(), message.end());
    EXPECT_EQ(borrowed, owned);
    owned.back().samples += 1;
    EXPECT_FALSE(borrowed == owned);
}

}  // namespace
}  // namespace aliquot
