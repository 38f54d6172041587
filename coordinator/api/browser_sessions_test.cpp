#include "browser_sessions.h"

#include <gtest/gtest.h>

#include <set>

namespace aliquot {
namespace {

using namespace std::chrono_literals;

// A clock the test moves by hand.
struct FakeClock {
    std::chrono::steady_clock::time_point now{};
    BrowserSessions::Clock get() {
        return [this] { return now; };
    }
};

TEST(BrowserSessions, AnIdIsRandomAndOpensOnlyItsSession) {
    BrowserSessions sessions;
    std::set<std::string> ids;
    for (int i = 0; i < 100; ++i) ids.insert(sessions.open());
    EXPECT_EQ(ids.size(), 100u);
    const std::string id = *ids.begin();
    EXPECT_EQ(id.size(), 64u);
    EXPECT_TRUE(sessions.use(id));
    std::string near = id;
    near.back() = near.back() == '0' ? '1' : '0';  // the same selector, another verifier
    EXPECT_FALSE(sessions.use(near));
    EXPECT_FALSE(sessions.use(id.substr(0, 32)));
    EXPECT_FALSE(sessions.use(""));
}

TEST(BrowserSessions, SigningOutEndsTheSession) {
    BrowserSessions sessions;
    const std::string id = sessions.open(), other = sessions.open();
    sessions.close(id);
    EXPECT_FALSE(sessions.use(id));
    EXPECT_TRUE(sessions.use(other));
    EXPECT_EQ(sessions.size(), 1u);
}

TEST(BrowserSessions, AnIdleSessionEndsAndAnOldOneEndsWhateverItsUse) {
    FakeClock clock;
    BrowserSessions sessions({.max_sessions = 10, .idle = 1h, .lifetime = 3h},
                             clock.get());
    const std::string idle = sessions.open(), busy = sessions.open();
    clock.now += 50min;
    EXPECT_TRUE(sessions.use(busy));
    clock.now += 50min;  // idle for 100 min, busy for 50
    EXPECT_FALSE(sessions.use(idle));
    EXPECT_TRUE(sessions.use(busy));
    for (int i = 0; i < 3; ++i) {
        clock.now += 40min;
        EXPECT_EQ(sessions.use(busy), i < 1) << i;  // ends 3 h after signing in
    }
}

TEST(BrowserSessions, TheTableIsBoundedAndDropsTheLeastRecentlyUsed) {
    FakeClock clock;
    BrowserSessions sessions({.max_sessions = 3}, clock.get());
    std::vector<std::string> ids;
    for (int i = 0; i < 3; ++i) {
        ids.push_back(sessions.open());
        clock.now += 1s;
    }
    EXPECT_TRUE(sessions.use(ids[0]));  // ids[1] is now the least recently used
    clock.now += 1s;
    const std::string fourth = sessions.open();
    EXPECT_EQ(sessions.size(), 3u);
    EXPECT_FALSE(sessions.use(ids[1]));
    EXPECT_TRUE(sessions.use(ids[0]));
    EXPECT_TRUE(sessions.use(ids[2]));
    EXPECT_TRUE(sessions.use(fourth));
    for (int i = 0; i < 1000; ++i) sessions.open();
    EXPECT_EQ(sessions.size(), 3u);
}

}  // namespace
}  // namespace aliquot
