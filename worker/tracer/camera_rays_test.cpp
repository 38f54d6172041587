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
// batch size (whole SIMD vectors and the remainder alike) and lanes from many pixels.
TEST(CameraRays, EachSampleGetsWhatItsOwnGeneratorWouldDraw) {
    const Scene scene = load_scene("cornell-box");
    const CameraModel camera(scene.camera, 97, 61);
    for (int n : {1, 2, 7, 16, 17, 33, PathLanes::kMax}) {
        const size_t count = static_cast<size_t>(n);
        std::vector<Vec3> dirs(count);
        std::vector<SampleRng> rngs(count, SampleRng(0, 0, 0, 0));
        const uint64_t seed = 12345;
        struct {
            uint32_t x[PathLanes::kMax], y[PathLanes::kMax];
            uint64_t k[PathLanes::kMax];
        } lanes;
        for (int j = 0; j < n; ++j) {  // a few samples of each of several pixels
            lanes.x[j] = 40 + uint32_t(j / 3) % 8;
            lanes.y[j] = 17 + uint32_t(j / 24);
            lanes.k[j] = 1000 + uint64_t(n) + uint64_t(j % 3);
        }
        camera_rays(camera, seed, lanes.x, lanes.y, lanes.k, n, dirs.data(), rngs.data());
        for (int j = 0; j < n; ++j) {
            SampleRng own(seed, lanes.x[j], lanes.y[j], lanes.k[j]);
            const float px = float(lanes.x[j]) + own.next_float();
            const float py = float(lanes.y[j]) + own.next_float();
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
    std::vector<uint32_t> xy(PathLanes::kMax + 1, 0);
    std::vector<uint64_t> k(PathLanes::kMax + 1, 0);
    EXPECT_THROW(camera_rays(camera, 1, xy.data(), xy.data(), k.data(),
                             PathLanes::kMax + 1, dirs.data(), rngs.data()),
                 std::invalid_argument);
}

}  // namespace
}  // namespace aliquot
