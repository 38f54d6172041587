#include "camera_rays.h"

#include <gtest/gtest.h>

#include <cstring>
#include <stdexcept>
#include <vector>

#include "path_lanes.h"
#include "scene_loader.h"

namespace aliquot {
namespace {

// The loop gives each sample what seeding its own SampleRng and drawing the pixel point
// from it would: the same ray to the bit and a generator in the same state, for every
// batch size (whole SIMD vectors and the remainder alike).
TEST(CameraRays, EachSampleGetsWhatItsOwnGeneratorWouldDraw) {
    const Scene scene = load_scene("cornell-box");
    const CameraModel camera(scene.camera, 97, 61);
    for (int n : {1, 2, 7, 16, 17, 33, PathLanes::kMax}) {
        const size_t count = static_cast<size_t>(n);
        std::vector<Vec3> dirs(count);
        std::vector<SampleRng> rngs(count, SampleRng(0, 0, 0, 0));
        const uint64_t seed = 12345, k0 = 1000 + uint64_t(n);
        const uint32_t x = 41, y = 17;
        camera_rays(camera, seed, x, y, k0, n, dirs.data(), rngs.data());
        for (int j = 0; j < n; ++j) {
            SampleRng own(seed, x, y, k0 + uint64_t(j));
            const float px = float(x) + own.next_float();
            const float py = float(y) + own.next_float();
            const Vec3 dir = camera.direction(px, py);
            EXPECT_EQ(std::memcmp(&dirs[size_t(j)], &dir, sizeof dir), 0)
                << n << ", " << j;
            EXPECT_EQ(rngs[size_t(j)].state(), own.state());
            EXPECT_EQ(rngs[size_t(j)].increment(), own.increment());
        }
    }
}

TEST(CameraRays, RefusesMoreSamplesThanABatch) {
    const Scene scene = load_scene("cornell-box");
    const CameraModel camera(scene.camera, 8, 8);
    std::vector<Vec3> dirs(PathLanes::kMax + 1);
    std::vector<SampleRng> rngs(PathLanes::kMax + 1, SampleRng(0, 0, 0, 0));
    EXPECT_THROW(
        camera_rays(camera, 1, 0, 0, 0, PathLanes::kMax + 1, dirs.data(), rngs.data()),
        std::invalid_argument);
}

}  // namespace
}  // namespace aliquot
