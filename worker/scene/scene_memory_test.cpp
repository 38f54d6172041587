// Out of memory while a scene from another machine is parsed: the parse fails with
// std::bad_alloc and the process goes on (issue 30, item 7).
#include "failing_allocator.h"
#include "mesh_scene_text.h"
#include "scene_loader.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

namespace aliquot {
namespace {

// prlimit --as=1300000000 and a 4 MB scene of 515k triangles: SIGABRT in
// parse_submitted_scene. The parse threw std::bad_alloc, and destroying the half-built
// JSON (nlohmann's noexcept destructor allocates a stack the size of the largest array)
// failed again: std::terminate. Each cap here fails the parse at another place; the
// process must survive every one (run apart, so that an abort fails this test only).
TEST(SubmittedScenesOutOfMemory, FailWithBadAllocAndNeverAbort) {
    const std::string text = testing::mesh_scene_text(20000);
    ASSERT_NO_THROW(parse_submitted_scene(text, "scene:h"));  // with memory enough
    for (const size_t cap : {size_t(512), size_t(4) << 10, size_t(64) << 10,
                             size_t(256) << 10, size_t(320) << 10}) {
        EXPECT_EXIT(
            {
                int outcome = 2;
                try {
                    testing::AllocationCap limit(cap);
                    parse_submitted_scene(text, "scene:h");
                    outcome = 1;
                } catch (const std::bad_alloc&) {
                    outcome = 0;
                } catch (...) {
                    outcome = 3;
                }
                std::_Exit(outcome);
            },
            ::testing::ExitedWithCode(0), "")
            << "allocations capped at " << cap << " bytes";
    }
    // And the same scene parses afterwards, memory being back.
    EXPECT_NO_THROW(parse_submitted_scene(text, "scene:h"));
}

}  // namespace
}  // namespace aliquot
