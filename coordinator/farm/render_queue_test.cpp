// The queue's positions and the order lease() serves renders in are one order
// (LeaseOrder), before and after a restart.
#include "render_queue.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <vector>

#include "coordinator.h"
#include "farm_test_results.h"

namespace aliquot {
namespace {

// Thousands queued, priorities changed and renders started at random: after every
// change, every position is the render's place in LeaseOrder.
TEST(RenderQueue, PositionsOfThousandsOfRendersFollowEveryChange) {
    struct Queued {
        std::string id;
        LeaseOrder order;
    };
    std::vector<Queued> expected;
    RenderQueue q;
    std::mt19937 random(7);
    for (uint64_t n = 0; n < 3000; ++n) {
        const int32_t priority = int32_t(random() % 5);
        expected.push_back({"r-" + std::to_string(n), {priority, n}});
        q.add(expected.back().id, priority, n);
    }
    for (int change = 0; change < 40; ++change) {
        Queued& some = expected[random() % expected.size()];
        if (change % 2 == 0) {
            some.order.priority = int32_t(random() % 5);
            q.set_priority(some.id, some.order.priority);
        } else {
            EXPECT_TRUE(q.leave(some.id));
            EXPECT_FALSE(q.leave(some.id));
            EXPECT_EQ(q.position(some.id), 0u);
            expected.erase(expected.begin() + (&some - expected.data()));
        }
        std::vector<Queued> sorted = expected;
        std::sort(sorted.begin(), sorted.end(),
                  [](const Queued& a, const Queued& b) { return a.order < b.order; });
        ASSERT_EQ(q.size(), sorted.size());
        for (size_t i = 0; i < sorted.size(); ++i)
            ASSERT_EQ(q.position(sorted[i].id), i + 1) << "change " << change;
    }
}

// A restarted coordinator resumes its renders in submission order, each with the
// priority it last had: the queue and the leases follow the order they had before.
TEST(RenderQueue, ResumedRendersKeepTheirPlaces) {
    CoordinatorOptions options;
    options.data_dir = std::filesystem::temp_directory_path() /
                       ("aliquot_render_queue_test_" + std::to_string(getpid()));
    std::filesystem::remove_all(options.data_dir);
    RenderSpec spec = small_test_spec();
    std::vector<std::string> ids;  // in the order they are to be leased
    {
        Coordinator c(options);
        const std::string a = c.submit(spec), b = c.submit(spec), d = c.submit(spec);
        spec.priority = 1;
        const std::string urgent = c.submit(spec);
        c.set_priority(d, 3);
        ids = {d, urgent, a, b};
        for (size_t i = 0; i < ids.size(); ++i)
            EXPECT_EQ(c.info(ids[i])->queue_position, i + 1) << ids[i];
    }
    Coordinator again(options);
    for (size_t i = 0; i < ids.size(); ++i)
        EXPECT_EQ(again.info(ids[i])->queue_position, i + 1) << ids[i];
    const std::string session = again.register_worker("w", 1).session;
    for (const std::string& id : ids) {
        const std::optional<LeaseGrant> grant =
            again.lease(session, std::chrono::milliseconds(0));
        ASSERT_TRUE(grant);
        EXPECT_EQ(grant->render_id, id);
    }
    std::filesystem::remove_all(options.data_dir);
}

}  // namespace
}  // namespace aliquot
