// Out of memory while a submitted scene is parsed: the submission fails with
// std::bad_alloc (the gRPC handler answers RESOURCE_EXHAUSTED) and the coordinator goes
// on (issue 30, item 7).
#include "coordinator.h"
#include "failing_allocator.h"
#include "mesh_scene_text.h"

#include <gtest/gtest.h>

#include <string>

namespace aliquot {
namespace {

// prlimit --as=1300000000 and a 4 MB scene of 515k triangles: SIGABRT in
// parse_submitted_scene, the coordinator gone.
TEST(SubmitOutOfMemory, ASceneThatDoesNotFitFailsItsSubmissionOnly) {
    CoordinatorOptions options;
    options.memory_limit = 0;
    Coordinator coordinator(options);
    RenderSpec spec;
    spec.scene_name = "large";
    spec.scene_json = testing::mesh_scene_text(20000);
    spec.width = spec.height = 8;
    spec.strategy.method = "uniform";
    spec.strategy.spp = 1;
    {
        RenderSpec copy = spec;  // made before the cap: the parse is what must fail
        testing::AllocationCap cap(64 << 10);
        EXPECT_THROW(coordinator.submit(std::move(copy)), std::bad_alloc);
    }
    EXPECT_TRUE(coordinator.list(10).empty());  // nothing claimed or kept
    EXPECT_EQ(coordinator.memory_in_use(), 0u);
    EXPECT_NO_THROW(coordinator.submit(spec));  // with memory back, the same scene
}

}  // namespace
}  // namespace aliquot
