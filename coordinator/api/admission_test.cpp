#include "admission.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace aliquot {
namespace {

// A place given back is the same peer's to take again, and a share is per address.
TEST(Admission, APeerHoldsAtMostItsShareAndGetsPlacesBackAsTheyGo) {
    Admission places(4, 3);
    std::vector<Admission::Place> held;
    for (int i = 0; i < 3; ++i) {
        Admission::Ticket t = places.take("10.0.0.1");
        ASSERT_TRUE(t.place) << i;
        held.push_back(std::move(t.place));
    }
    const Admission::Ticket past_share = places.take("10.0.0.1");
    EXPECT_FALSE(past_share.place);
    EXPECT_TRUE(past_share.peer_share_full);
    Admission::Ticket other = places.take("10.0.0.2");
    ASSERT_TRUE(other.place);
    // Every place taken: refused for the places in all, not for a share.
    const Admission::Ticket full = places.take("10.0.0.3");
    EXPECT_FALSE(full.place);
    EXPECT_FALSE(full.peer_share_full);
    EXPECT_EQ(places.taken(), 4u);

    held.pop_back();  // a copy kept elsewhere would hold it: the last one gives it back
    EXPECT_EQ(places.taken(), 3u);
    EXPECT_TRUE(places.take("10.0.0.1").place);
    other.place.reset();
    held.clear();
    EXPECT_EQ(places.taken(), 0u);
}

// A share larger than the places is the places: one address may take them all.
TEST(Admission, AShareLargerThanThePlacesIsThePlaces) {
    Admission places(2, 6);
    EXPECT_EQ(places.places_per_peer(), 2u);
    const Admission::Place a = places.take("p").place, b = places.take("p").place;
    EXPECT_TRUE(a && b);
    const Admission::Ticket c = places.take("p");
    EXPECT_FALSE(c.place);
    EXPECT_FALSE(c.peer_share_full);
}

// Refused peers leave nothing behind: with a share of 0 every caller is refused, and
// the account of addresses stayed one entry a caller (the map grew without bound).
TEST(Admission, RefusedPeersLeaveNoEntryBehind) {
    Admission none(4, 0);
    for (int i = 0; i < 100; ++i) {
        const Admission::Ticket t = none.take("10.0.0." + std::to_string(i));
        EXPECT_FALSE(t.place);
        EXPECT_TRUE(t.peer_share_full);
    }
    EXPECT_EQ(none.peers(), 0u);
    Admission one(2, 1);
    const Admission::Place held = one.take("p").place;
    ASSERT_TRUE(held);
    for (int i = 0; i < 10; ++i) EXPECT_FALSE(one.take("p").place);
    EXPECT_EQ(one.peers(), 1u);
}

}  // namespace
}  // namespace aliquot
