#include "camera_rays.h"

#include <stdexcept>

#include "simd_clones.h"

namespace aliquot {

ALIQUOT_SIMD_CLONES void camera_rays(const CameraModel& camera, uint64_t seed,
                                     const uint32_t* xs, const uint32_t* ys,
                                     const uint64_t* ks, int n, Vec3* dirs,
                                     SampleRng* rngs) {
    constexpr int kMax = PathLanes::kMax;
    if (n < 0 || n > kMax)
        throw std::invalid_argument("camera_rays: more samples than a batch");
    uint64_t state[kMax], inc[kMax];
    float dx[kMax], dy[kMax], dz[kMax];
    const CameraModel cam = camera;  // a local copy: nothing the loop stores can alias it
    for (int j = 0; j < n; ++j) {
        const uint32_t x = xs[j], y = ys[j];
        uint64_t s, i;
        seed_pcg(seed, x, y, ks[j], s, i);
        // Through int32: a signed conversion is one vector instruction, an unsigned one
        // is several without AVX-512; a pixel's coordinates are far below 2^31.
        const float px = float(int32_t(x)) + unit_float(pcg32_step(s, i));
        const float py = float(int32_t(y)) + unit_float(pcg32_step(s, i));
        const Vec3 d = cam.direction(px, py);
        state[j] = s;
        inc[j] = i;
        dx[j] = d.x, dy[j] = d.y, dz[j] = d.z;
    }
    for (int j = 0; j < n; ++j) {
        dirs[j] = Vec3(dx[j], dy[j], dz[j]);
        rngs[j] = SampleRng::at(state[j], inc[j]);
    }
}

}  // namespace aliquot
