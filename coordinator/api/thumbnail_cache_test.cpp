#include "thumbnail_cache.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace aliquot {
namespace {

TEST(ThumbnailCache, MakesAThumbnailOncePerVersion) {
    ThumbnailCache cache(4);
    int made = 0;
    auto make = [&] { return "png" + std::to_string(++made); };
    EXPECT_EQ(cache.get("r-1", "10", make), "png1");
    EXPECT_EQ(cache.get("r-1", "10", make), "png1");
    EXPECT_EQ(cache.get("r-1", "20", make), "png2");
    EXPECT_EQ(made, 2);
    EXPECT_EQ(cache.made(), 2u);
}

// Hostile: a list of thousands of renders asked for one after another keeps memory
// bounded.
TEST(ThumbnailCache, KeepsAtMostItsCapacityDroppingTheLeastRecentlyAsked) {
    ThumbnailCache cache(3);
    for (int i = 0; i < 1000; ++i)
        cache.get("r-" + std::to_string(i), "1", [] { return std::string(100, 'p'); });
    EXPECT_EQ(cache.size(), 3u);
    int made = 0;
    auto make = [&] { return std::to_string(++made); };
    cache.get("r-997", "1", make);  // kept: the three most recent
    EXPECT_EQ(made, 0);
    cache.get("r-997", "1", make);  // now r-998 is the least recent
    cache.get("r-5", "1", make);    // evicts r-998
    cache.get("r-999", "1", make);
    EXPECT_EQ(made, 1);
    cache.get("r-998", "1", make);
    EXPECT_EQ(made, 2);
}

TEST(ThumbnailCache, AFailedMakeKeepsNothingAndForgetDropsOne) {
    ThumbnailCache cache(2);
    EXPECT_THROW(
        cache.get("r-1", "1", []() -> std::string { throw std::runtime_error("x"); }),
        std::runtime_error);
    EXPECT_EQ(cache.size(), 0u);
    cache.get("r-1", "1", [] { return std::string("a"); });
    cache.forget("r-1");
    cache.forget("r-unknown");
    EXPECT_EQ(cache.size(), 0u);
}

}  // namespace
}  // namespace aliquot
