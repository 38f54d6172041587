// What a round end allocates: `optimal` keeps the buffers it plans in from one round end
// to the next (taking megabytes of fresh pages each round end was most of some passes'
// time at 1920x1080), so after the first plans a round end allocates little beyond the
// round's own counts, which it hands over. Counted by replacing the global allocation
// functions in this test binary: they count bytes while a test asks, and allocate as
// usual.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "bands.h"
#include "round_cutter.h"
#include "strategy_params.h"
#include "synthetic_source.h"

namespace {
std::atomic<bool> counting{false};
std::atomic<uint64_t> bytes_counted{0};
}  // namespace

void* operator new(std::size_t size) {
    if (counting.load(std::memory_order_relaxed))
        bytes_counted.fetch_add(size, std::memory_order_relaxed);
    if (void* p = std::malloc(size ? size : 1)) return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace aliquot {
namespace {

// Bytes allocated while `f` runs (any thread).
template <typename F>
uint64_t bytes_allocated_by(F&& f) {
    bytes_counted = 0;
    counting = true;
    f();
    counting = false;
    return bytes_counted.load();
}

// Several bands of pixels (the image median's histograms are per band), noise that
// varies, and fireflies: every steered round passes over most of the image.
SyntheticImage noisy_image() {
    SyntheticImage image(512, 300, 5);
    for (uint32_t y = 0; y < image.height(); ++y)
        for (uint32_t x = 0; x < image.width(); ++x) {
            SyntheticPixel& p = image.at(x, y);
            p.mean = 0.2 + 0.5 * double(x) / image.width();
            p.sigma = (x / 24 + y / 24) % 3 == 0 ? 0.5 : 0.03 * (1 + y % 5);
            if ((x * 13 + y * 7) % 89 == 0) {
                p.firefly_probability = 0.03;
                p.firefly_value = 20;
            }
        }
    return image;
}

// Each call of `method`'s next_round in a 64-spp render (with the work it leaves ahead):
// the bytes it allocated beyond the round's own counts, and whether it gave a round (the
// last gives none).
struct RoundEndBytes {
    uint64_t extra = 0;
    bool round = false;
};
std::vector<RoundEndBytes> bytes_of_each_round_end(const char* method,
                                                   uint32_t sigma_self_out = 0) {
    const unsigned threads = band_threads();
    set_band_threads(1);  // the pool's own bookkeeping is not the strategy's
    const SyntheticImage image = noisy_image();
    StrategyParams params;
    params.method = method;
    params.spp = 64;
    params.sigma_self_out = sigma_self_out;
    const auto strategy = make_strategy(params, image.width(), image.height());
    Accumulator merged(image.width(), image.height());
    std::vector<RoundEndBytes> ends;
    for (int r = 0; r < 20; ++r) {
        std::optional<Round> round;
        const uint64_t bytes = bytes_allocated_by([&] {
            round = strategy->next_round(merged);
            if (auto work = strategy->take_work_ahead()) work();
        });
        const uint64_t counts = round ? round->spp.size() * sizeof(uint32_t) : 0;
        ends.push_back({bytes > counts ? bytes - counts : 0, round.has_value()});
        if (!round) break;
        for (const SampleJob& job : cut_round(*round, merged))
            merged.merge(image.trace(job));
    }
    set_band_threads(threads);
    return ends;
}

// Each round end of `method`, after the first two: bytes allocated beyond the round's own
// counts.
std::vector<uint64_t> extra_bytes_a_round_end(const char* method,
                                              uint32_t sigma_self_out = 0) {
    std::vector<uint64_t> extra;
    const std::vector<RoundEndBytes> ends =
        bytes_of_each_round_end(method, sigma_self_out);
    for (size_t r = 2; r < ends.size(); ++r)
        if (ends[r].round) extra.push_back(ends[r].extra);
    return extra;
}

TEST(RoundEndAllocation, OptimalKeepsItsPlanningBuffersFromRoundToRound) {
    const uint64_t pixels = noisy_image().pixel_count();
    for (const char* method : {"optimal", "optimal-time"}) {
        const std::vector<uint64_t> extra = extra_bytes_a_round_end(method);
        ASSERT_GE(extra.size(), 4u) << method;
        // A plan reads and writes ~10 vectors of a pixel each; taken anew each round
        // end they were ~15 bytes a pixel here (the weights copied, the median's and
        // apportion's per-band histograms). What is left is per-band sums and the like.
        for (size_t k = 0; k < extra.size(); ++k)
            EXPECT_LT(extra[k], pixels) << method << ", round end " << k + 2;
    }
}

// sigma_self_out's neighbours' means are written into the sigma buffer the plan keeps,
// with two rows of column sums a band beside it: no image-sized buffer of its own.
TEST(RoundEndAllocation, SigmaSelfOutPlansInTheSameBuffers) {
    const uint64_t pixels = noisy_image().pixel_count();
    for (const char* method : {"optimal", "optimal-time"}) {
        const std::vector<uint64_t> extra = extra_bytes_a_round_end(method, 3);
        ASSERT_GE(extra.size(), 4u) << method;
        for (size_t k = 0; k < extra.size(); ++k)
            EXPECT_LT(extra[k], pixels) << method << ", round end " << k + 2;
    }
}

// What a whole render's round ends allocate beyond the rounds' own counts, a pixel: the
// planning buffers, taken once (their pages faulted in once, ~0.1 s at 1920x1080). sigma,
// the weights and the gaps are worked in one buffer, and optimal sorts no remainder keys
// (optimal-time does): 74 and 86 bytes a pixel here with a buffer each, 42 and 70 now.
uint64_t bytes_a_pixel_over_a_render(const char* method) {
    uint64_t extra = 0;
    for (const RoundEndBytes& end : bytes_of_each_round_end(method)) extra += end.extra;
    return extra / noisy_image().pixel_count();
}

TEST(RoundEndAllocation, OptimalPlansInOneBufferForSigmaWeightsAndGaps) {
    EXPECT_LE(bytes_a_pixel_over_a_render("optimal"), 50u);
    EXPECT_LE(bytes_a_pixel_over_a_render("optimal-time"), 78u);
}

}  // namespace
}  // namespace aliquot
