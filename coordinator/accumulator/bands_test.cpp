#include "bands.h"

#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <set>
#include <thread>

namespace aliquot {
namespace {

// The threads a pass of many bands ran on, started on a thread of its own (after
// `prepare` has run there).
template <typename Prepare>
std::set<std::thread::id> threads_of_a_pass(const Prepare& prepare) {
    std::set<std::thread::id> ran_on;
    std::mutex mutex;
    std::thread caller([&] {
        prepare();
        for_each_band(64 * 1024, 16, [&](size_t, size_t, size_t) {
            std::this_thread::sleep_for(std::chrono::microseconds(20));
            std::lock_guard lock(mutex);
            ran_on.insert(std::this_thread::get_id());
        });
        std::lock_guard lock(mutex);
        ran_on.insert(std::this_thread::get_id());  // the caller, last
    });
    caller.join();
    return ran_on;
}

// The record writer's passes (at nice 10) stay on its thread: they neither take the pool
// from a round end nor start its threads, which would inherit the writer's priority.
TEST(Bands, APassOnAThreadThatKeepsItsPassesRunsThereAlone) {
    const unsigned before = band_threads();
    set_band_threads(4);
    EXPECT_EQ(threads_of_a_pass([] { keep_passes_on_this_thread(); }).size(), 1u);
    // The same pass elsewhere is shared: 4096 bands of 20 us leave the pool's threads
    // time to take some.
    EXPECT_GT(threads_of_a_pass([] {}).size(), 1u);
    set_band_threads(before);
}

}  // namespace
}  // namespace aliquot
