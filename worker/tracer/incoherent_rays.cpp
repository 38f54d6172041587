#include "incoherent_rays.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "sampler.h"

namespace aliquot {

std::vector<RawRay> incoherent_rays(const Scene& scene, size_t count) {
    Vec3 lo(1e30f), hi(-1e30f);
    for (const TriangleMesh& m : scene.meshes)
        for (const Vec3& p : m.positions) {
            lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
            hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
        }
    const Vec3 extent = hi - lo;
    std::vector<RawRay> rays(count);
    for (size_t i = 0; i < count; ++i) {
        SampleRng rng(12345, 0, 0, i);
        const Vec3 o = lo + extent * Vec3(0.01f + 0.98f * rng.next_float(),
                                          0.01f + 0.98f * rng.next_float(),
                                          0.01f + 0.98f * rng.next_float());
        const float z = 1.0f - 2.0f * rng.next_float();
        const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const float phi = 2.0f * float(std::numbers::pi) * rng.next_float();
        rays[i] = {o, {r * std::cos(phi), r * std::sin(phi), z}};
    }
    return rays;
}

}  // namespace aliquot
