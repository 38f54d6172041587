#include "thumbnail_cache.h"

#include <gtest/gtest.h>

#include <cmath>
#include <new>
#include <stdexcept>

#include "accumulator.h"
#include "failing_allocator.h"  // this binary's only: it replaces operator new
#include "http_api.h"

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

// A render's sums over its whole image: smooth, with an edge and a few bright pixels, and
// pixels of no samples, so that box filtering and rounding both matter.
Accumulator sums_of(uint32_t width, uint32_t height) {
    Accumulator sums(width, height);
    SampleJobResult result;
    result.rect = {0, 0, width, height};
    result.pixels.resize(result.rect.size());
    for (size_t i = 0; i < result.pixels.size(); ++i) {
        const uint32_t x = uint32_t(i % width), y = uint32_t(i / width);
        PixelSums& p = result.pixels[i];
        p.samples = (x + y) % 7 == 0 ? 0 : 1 + (x * 3 + y) % 5;
        const double v = 0.1 + 0.3 * std::sin(0.05 * x) * std::cos(0.07 * y) +
                         (x > width / 2 ? 0.4 : 0) + (i % 97 == 0 ? 20 : 0);
        for (int c = 0; c < 3; ++c) {
            p.even[c] = double(p.samples / 2) * v * (1 + 0.1 * c);
            p.odd[c] = double(p.samples - p.samples / 2) * v * (1 - 0.1 * c);
        }
        p.sum_sq_luminance = double(p.samples) * v * v;
        p.rays = p.samples;
    }
    sums.merge(result);
    return sums;
}

// Issue 32 review: a thumbnail of a render in memory is made from its sums, the same
// bytes as the preview of its full-size image shrunk, at sizes that divide and do not.
TEST(ThumbnailPng, FromTheSumsIsThePreviewOfTheFullSizeImage) {
    struct Case {
        uint32_t w, h, side;
    };
    for (const auto& [w, h, side] :
         {Case{37, 23, 8}, Case{200, 120, 96}, Case{96, 50, 96}, Case{5, 300, 96}}) {
        const Accumulator sums = sums_of(w, h);
        EXPECT_EQ(http_api::thumbnail_png(sums, side),
                  http_api::preview_png(sums.image(), 0, side))
            << w << "x" << h << " into " << side;
    }
}

// And it never makes the full-size image: with every allocation of the thread capped at
// a sixth of that image's floats, the thumbnail is made and the image is not.
TEST(ThumbnailPng, FromTheSumsMakesNoFullSizeImage) {
    const Accumulator sums = sums_of(1024, 768);
    const size_t image_bytes = size_t(1024) * 768 * 3 * sizeof(float);
    std::string thumbnail;
    {
        const testing::AllocationCap cap(image_bytes / 6);
        thumbnail = http_api::thumbnail_png(sums, 96);
        EXPECT_THROW(sums.image(), std::bad_alloc);  // the cap does bind the image
    }
    EXPECT_EQ(thumbnail, http_api::preview_png(sums.image(), 0, 96));
}

}  // namespace
}  // namespace aliquot
