#include "embree_scene.h"

#include "log_line.h"
#include "sphere_hit.h"
#include "sphere_lanes.h"

#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <stdexcept>
#include <string>

namespace aliquot {

namespace {

// Installed before any other call, so that no Embree call needs its own error check:
// configuration errors surface here, and construction fails below.
void on_embree_error(void*, RTCError code, const char* message) {
    write_log_warning("embree_error", {log_number("code", int64_t(code)),
                                       log_text("message", message ? message : "")});
}

void throw_if_failed(RTCDevice device, const char* what) {
    const RTCError err = rtcGetDeviceError(device);
    if (err != RTC_ERROR_NONE) {
        throw std::runtime_error(std::string("embree failed to ") + what + " (error " +
                                 std::to_string(int(err)) + ")");
    }
}

// A geometry's new buffer. Out of memory, Embree calls the error function and returns
// null, which is not to be written through: the geometry is released and this throws,
// so that a worker reports the job it cannot trace instead of crashing.
void* new_buffer(RTCDevice device, RTCGeometry geom, RTCBufferType type, RTCFormat format,
                 size_t stride, size_t count) {
    void* buffer = rtcSetNewGeometryBuffer(geom, type, 0, format, stride, count);
    if (!buffer) {
        rtcReleaseGeometry(geom);
        throw_if_failed(device, "allocate a geometry buffer");
        throw std::runtime_error("embree failed to allocate a geometry buffer");
    }
    return buffer;
}

RTCGeometry new_geometry(RTCDevice device, RTCGeometryType type) {
    RTCGeometry geom = rtcNewGeometry(device, type);
    if (!geom) {
        throw_if_failed(device, "make a geometry");
        throw std::runtime_error("embree failed to make a geometry");
    }
    return geom;
}

// Paths' rays go every which way: Embree is told so (it matters for its stream paths).
RTCIntersectContext incoherent_context() {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    return context;
}

RTCRay single_ray(const Vec3& origin, const Vec3& dir, float tmax) {
    RTCRay ray;
    ray.org_x = origin.x;
    ray.org_y = origin.y;
    ray.org_z = origin.z;
    ray.dir_x = dir.x;
    ray.dir_y = dir.y;
    ray.dir_z = dir.z;
    ray.tnear = 0.0f;
    ray.tfar = tmax;
    ray.time = 0.0f;
    ray.mask = ~0u;
    ray.id = 0;
    ray.flags = 0;
    return ray;
}

}  // namespace

// Rectangles and cube faces arrive as triangle pairs (a0, a1, a2), (a0, a2, b2). Embree
// intersects such a pair as one quad noticeably faster than as two triangles (a tiny
// scene's rays are dominated by per-primitive tests), so a mesh made only of such pairs
// becomes a quad mesh.
bool pairs_into_quads(const TriangleMesh& mesh) {
    if (mesh.triangles.empty() || mesh.triangles.size() % 2 != 0) return false;
    for (size_t i = 0; i < mesh.triangles.size(); i += 2) {
        const auto& a = mesh.triangles[i];
        const auto& b = mesh.triangles[i + 1];
        if (b[0] != a[0] || b[1] != a[2]) return false;
    }
    return true;
}

// Scenes made of a few simple shapes (every built-in scene) trace faster through Embree's
// two-level BVH, one small BVH per shape under a top-level one, which it builds for
// RTC_BUILD_QUALITY_LOW: on cornell-box 26 % fewer instructions a sample than its
// one-level SAH BVH, where leaves mix quads of different walls. A large mesh is better
// served by the SAH build (the two-level build makes each mesh's own BVH by Morton
// codes).
bool two_level_bvh(const Scene& scene) {
    constexpr size_t kSmallMesh = 256;  // triangles
    for (const TriangleMesh& mesh : scene.meshes)
        if (mesh.triangles.size() > kSmallMesh) return false;
    return true;
}

void enable_flush_to_zero() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

EmbreeScene::EmbreeScene(const Scene& scene) {
    enable_flush_to_zero();
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("embree: cannot create a device");
    rtcSetDeviceErrorFunction(device_, on_embree_error, nullptr);
    // No destructor runs for a constructor that throws (out of memory, in Embree or in
    // a vector here): what was made so far is released on the way out.
    struct ReleaseOnThrow {
        EmbreeScene& self;
        const int uncaught = std::uncaught_exceptions();
        ~ReleaseOnThrow() {
            if (std::uncaught_exceptions() == uncaught) return;
            if (self.scene_) rtcReleaseScene(self.scene_);
            rtcReleaseDevice(self.device_);
            self.scene_ = nullptr;
            self.device_ = nullptr;
        }
    } release_on_throw{*this};
    scene_ = rtcNewScene(device_);
    if (!scene_) throw std::runtime_error("embree failed to make a scene");
    rtcSetSceneBuildQuality(
        scene_, two_level_bvh(scene) ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_HIGH);

    for (const TriangleMesh& mesh : scene.meshes) {
        const bool quads = pairs_into_quads(mesh);
        MeshInfo& info = meshes_.emplace_back();
        info.quads = quads;
        std::vector<Vec3>& normals = info.normals;
        normals.reserve(mesh.triangles.size());
        for (const auto& tri : mesh.triangles) {
            const Vec3 p0 = mesh.positions[tri[0]];
            const Vec3 n =
                cross(mesh.positions[tri[1]] - p0, mesh.positions[tri[2]] - p0);
            const float len = length(n);
            normals.push_back(len > 0 ? n / len
                                      : Vec3(0, 0, 1));  // degenerate: never hit
        }
        RTCGeometry geom = new_geometry(
            device_, quads ? RTC_GEOMETRY_TYPE_QUAD : RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* v = static_cast<float*>(new_buffer(device_, geom, RTC_BUFFER_TYPE_VERTEX,
                                                 RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                 mesh.positions.size()));
        for (size_t i = 0; i < mesh.positions.size(); ++i) {
            v[3 * i] = mesh.positions[i].x;
            v[3 * i + 1] = mesh.positions[i].y;
            v[3 * i + 2] = mesh.positions[i].z;
        }
        if (quads) {
            // Embree splits quad (v0, v1, v2, v3) into triangles (v0, v1, v3) and
            // (v2, v3, v1). Pair a = (a0, a1, a2), b = (a0, a2, b2) as (a1, a2, b2, a0):
            // the halves are exactly a and b, same vertices, winding and diagonal.
            const size_t count = mesh.triangles.size() / 2;
            auto* idx = static_cast<unsigned*>(
                new_buffer(device_, geom, RTC_BUFFER_TYPE_INDEX, RTC_FORMAT_UINT4,
                           4 * sizeof(unsigned), count));
            for (size_t i = 0; i < count; ++i) {
                const auto& a = mesh.triangles[2 * i];
                const auto& b = mesh.triangles[2 * i + 1];
                idx[4 * i] = a[1];
                idx[4 * i + 1] = a[2];
                idx[4 * i + 2] = b[2];
                idx[4 * i + 3] = a[0];
            }
        } else {
            auto* idx = static_cast<unsigned*>(
                new_buffer(device_, geom, RTC_BUFFER_TYPE_INDEX, RTC_FORMAT_UINT3,
                           3 * sizeof(unsigned), mesh.triangles.size()));
            for (size_t i = 0; i < mesh.triangles.size(); ++i)
                for (int k = 0; k < 3; ++k) idx[3 * i + k] = mesh.triangles[i][k];
        }
        rtcCommitGeometry(geom);
        rtcAttachGeometry(scene_, geom);  // ids are sequential: geom id == mesh index
        rtcReleaseGeometry(geom);
    }

    // A few spheres stay out of Embree's BVH: each query tests them itself
    // (sphere_hit.h), faster than Embree's point spheres. Many go into it as point
    // spheres, since a test of every sphere by every ray grows with their number and a
    // BVH does not (a 4 MB scene can hold tens of thousands). Either way their geometry
    // id is one past the meshes'.
    sphere_geom_id_ = uint32_t(meshes_.size());
    if (scene.spheres.size() <= kOwnSpheres) {
        spheres_ = scene.spheres;
    } else {
        RTCGeometry geom = new_geometry(device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
        auto* v = static_cast<float*>(new_buffer(device_, geom, RTC_BUFFER_TYPE_VERTEX,
                                                 RTC_FORMAT_FLOAT4, 4 * sizeof(float),
                                                 scene.spheres.size()));
        for (size_t i = 0; i < scene.spheres.size(); ++i) {
            v[4 * i] = scene.spheres[i].center.x;
            v[4 * i + 1] = scene.spheres[i].center.y;
            v[4 * i + 2] = scene.spheres[i].center.z;
            v[4 * i + 3] = scene.spheres[i].radius;
        }
        rtcCommitGeometry(geom);
        rtcAttachGeometryByID(scene_, geom, sphere_geom_id_);
        rtcReleaseGeometry(geom);
    }

    rtcCommitScene(scene_);
    throw_if_failed(device_, "build the scene");
}

EmbreeScene::~EmbreeScene() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
}

Hit EmbreeScene::to_hit(float t, uint32_t geom, uint32_t prim, float u, float v,
                        const Vec3& embree_ng) const {
    Hit hit;
    hit.t = t;
    hit.geom_id = geom;
    if (geom == sphere_geom_id_) {  // one of many spheres, in Embree's BVH
        hit.prim_id = prim;
        hit.ng = normalize(embree_ng);
        return hit;
    }
    // A quad's second half (v2, v3, v1) has u + v > 1 in the quad's parametrisation.
    const MeshInfo& mesh = meshes_[geom];
    hit.prim_id = mesh.quads ? 2 * prim + (u + v > 1.0f) : prim;
    // Embree's Ng has the same direction (counter-clockwise winding); the unit normal
    // made once per triangle saves a square root and a division on every hit.
    hit.ng = mesh.normals[hit.prim_id];
    return hit;
}

bool EmbreeScene::nearer_sphere(const Vec3& origin, const Vec3& dir, float tmax,
                                Hit& hit) const {
    int nearest = -1;
    for (size_t i = 0; i < spheres_.size(); ++i) {
        const float t =
            sphere_hit_t(origin, dir, spheres_[i].center, spheres_[i].radius, tmax);
        if (t < tmax) {
            tmax = t;
            nearest = int(i);
        }
    }
    if (nearest < 0) return false;
    hit = sphere_hit(origin, dir, tmax, nearest);
    return true;
}

Hit EmbreeScene::sphere_hit(const Vec3& origin, const Vec3& dir, float t,
                            int sphere) const {
    Hit hit;
    hit.t = t;
    hit.geom_id = sphere_geom_id_;
    hit.prim_id = uint32_t(sphere);
    hit.ng = normalize(origin + dir * t - spheres_[size_t(sphere)].center);
    return hit;
}

bool EmbreeScene::sphere_blocks(const Vec3& origin, const Vec3& dir, float tmax) const {
    for (const Sphere& s : spheres_)
        if (sphere_hit_t(origin, dir, s.center, s.radius, tmax) < tmax) return true;
    return false;
}

namespace {

// Lanes [0, N) of an Embree packet from rays [0, count) of `rays`, each looking as far as
// tfar[i] (nullptr: to infinity); lanes past the count repeat lane 0 (the caller masks
// them off). Whole fields copied at once (a fixed size: a few vector moves), then the
// lanes past the count, rather than a lane at a time with a select per field.
template <int N, typename RayN>
void fill_lanes(RayN& ray, const RayLanes& rays, int count, const float* tfar) {
    static_assert(N <= RayLanes::kMax);
    constexpr size_t kBytes = N * sizeof(float);
    std::memcpy(ray.org_x, rays.ox, kBytes);
    std::memcpy(ray.org_y, rays.oy, kBytes);
    std::memcpy(ray.org_z, rays.oz, kBytes);
    std::memcpy(ray.dir_x, rays.dx, kBytes);
    std::memcpy(ray.dir_y, rays.dy, kBytes);
    std::memcpy(ray.dir_z, rays.dz, kBytes);
    if (tfar)
        std::memcpy(ray.tfar, tfar, kBytes);
    else
        for (int i = 0; i < N; ++i) ray.tfar[i] = std::numeric_limits<float>::infinity();
    for (int i = count; i < N; ++i) {
        ray.org_x[i] = rays.ox[0];
        ray.org_y[i] = rays.oy[0];
        ray.org_z[i] = rays.oz[0];
        ray.dir_x[i] = rays.dx[0];
        ray.dir_y[i] = rays.dy[0];
        ray.dir_z[i] = rays.dz[0];
        ray.tfar[i] = ray.tfar[0];
    }
    for (int i = 0; i < N; ++i) {
        ray.tnear[i] = 0.0f;
        ray.time[i] = 0.0f;
        ray.mask[i] = ~0u;
        ray.id[i] = unsigned(i);
        ray.flags[i] = 0;
    }
}

static_assert(RayLanes::kMax == EmbreeScene::kPacket, "a packet's rays fit its lanes");

void check_count(int count) {
    if (count < 0 || count > EmbreeScene::kPacket)
        throw std::invalid_argument("packet query: more rays than a packet holds");
}

// Embree's packet queries by width, so one template serves 4, 8 and 16.
void occluded_n(const int* v, RTCScene s, RTCIntersectContext* c, RTCRay4* r) {
    rtcOccluded4(v, s, c, r);
}
void occluded_n(const int* v, RTCScene s, RTCIntersectContext* c, RTCRay8* r) {
    rtcOccluded8(v, s, c, r);
}
void occluded_n(const int* v, RTCScene s, RTCIntersectContext* c, RTCRay16* r) {
    rtcOccluded16(v, s, c, r);
}
void intersect_n(const int* v, RTCScene s, RTCIntersectContext* c, RTCRayHit4* r) {
    rtcIntersect4(v, s, c, r);
}
void intersect_n(const int* v, RTCScene s, RTCIntersectContext* c, RTCRayHit8* r) {
    rtcIntersect8(v, s, c, r);
}
void intersect_n(const int* v, RTCScene s, RTCIntersectContext* c, RTCRayHit16* r) {
    rtcIntersect16(v, s, c, r);
}

// Lanes past the count repeat lane 0 and are masked off.
template <int N, typename RayN>
void occluded_width(RTCScene scene, const RayLanes& rays, int count, bool* occluded) {
    RTCIntersectContext context = incoherent_context();
    alignas(64) RayN ray;
    alignas(64) int valid[N];
    for (int i = 0; i < N; ++i) valid[i] = i < count ? -1 : 0;
    fill_lanes<N>(ray, rays, count, rays.t);
    occluded_n(valid, scene, &context, &ray);
    // Embree marks an occluded ray by setting tfar to -inf.
    for (int i = 0; i < count; ++i) occluded[i] = ray.tfar[i] < 0.0f;
}

// Closest hits of `count` <= N rays; calls on_hit(i, t, geom, prim, u, v, ng) for those
// that hit and sets found[i] for all.
template <int N, typename RayHitN, typename OnHit>
void intersect_width(RTCScene scene, const RayLanes& rays, int count, bool coherent,
                     bool* found, OnHit on_hit) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                             : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    alignas(64) RayHitN rh;
    alignas(64) int valid[N];
    for (int i = 0; i < N; ++i) {
        valid[i] = i < count ? -1 : 0;
        rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    fill_lanes<N>(rh.ray, rays, count, nullptr);
    intersect_n(valid, scene, &context, &rh);
    for (int i = 0; i < count; ++i) {
        found[i] = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
        if (found[i])
            on_hit(i, rh.ray.tfar[i], rh.hit.geomID[i], rh.hit.primID[i], rh.hit.u[i],
                   rh.hit.v[i], Vec3(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]));
    }
}

}  // namespace

void EmbreeScene::intersect_packet(const Vec3& origin, const Vec3* dirs, int count,
                                   Hit* hits, bool* found) const {
    check_count(count);
    RayLanes rays;
    for (int i = 0; i < count; ++i)
        rays.set(i, origin, dirs[i], std::numeric_limits<float>::infinity());
    intersect_lanes(rays, count, hits, found, true);
}

void EmbreeScene::intersect_packet(const Vec3* origins, const Vec3* dirs, int count,
                                   Hit* hits, bool* found, bool coherent) const {
    check_count(count);
    RayLanes rays;
    for (int i = 0; i < count; ++i)
        rays.set(i, origins[i], dirs[i], std::numeric_limits<float>::infinity());
    intersect_lanes(rays, count, hits, found, coherent);
}

void EmbreeScene::occluded_packet(const Vec3* origins, const Vec3* dirs,
                                  const float* tmax, int count, bool* occluded) const {
    check_count(count);
    RayLanes rays;
    for (int i = 0; i < count; ++i) rays.set(i, origins[i], dirs[i], tmax[i]);
    occluded_lanes(rays, count, occluded);
}

// The narrowest packet that holds `count` rays: Embree's packet kernels cost about the
// same per query whatever lanes are masked off, so a few rays in a 16-wide packet would
// cost more than one query each. One ray alone takes the single-ray kernel. The width is
// a function of the count, so the result is too.
void EmbreeScene::occluded_lanes(RayLanes& rays, int count, bool* occluded) const {
    check_count(count);
    if (count == 1) {
        occluded[0] = this->occluded(rays.origin(0), rays.dir(0), rays.t[0]);
        return;
    }
    if (count <= 4)
        occluded_width<4, RTCRay4>(scene_, rays, count, occluded);
    else if (count <= 8)
        occluded_width<8, RTCRay8>(scene_, rays, count, occluded);
    else
        occluded_width<16, RTCRay16>(scene_, rays, count, occluded);
    if (spheres_.empty()) return;
    nearest_spheres(spheres_, rays, count);
    for (int i = 0; i < count; ++i) occluded[i] = occluded[i] || rays.sphere[i] >= 0;
}

void EmbreeScene::intersect_lanes(RayLanes& rays, int count, Hit* hits, bool* found,
                                  bool coherent) const {
    check_count(count);
    if (count == 1) {
        found[0] = intersect(rays.origin(0), rays.dir(0),
                             std::numeric_limits<float>::infinity(), hits[0]);
        return;
    }
    const auto on_hit = [&](int i, float t, uint32_t geom, uint32_t prim, float u,
                            float v, const Vec3& ng) {
        hits[i] = to_hit(t, geom, prim, u, v, ng);
    };
    if (count <= 4)
        intersect_width<4, RTCRayHit4>(scene_, rays, count, coherent, found, on_hit);
    else if (count <= 8)
        intersect_width<8, RTCRayHit8>(scene_, rays, count, coherent, found, on_hit);
    else
        intersect_width<16, RTCRayHit16>(scene_, rays, count, coherent, found, on_hit);
    if (spheres_.empty()) return;
    for (int i = 0; i < count; ++i)
        rays.t[i] = found[i] ? hits[i].t : std::numeric_limits<float>::infinity();
    nearest_spheres(spheres_, rays, count);
    for (int i = 0; i < count; ++i)
        if (rays.sphere[i] >= 0) {
            hits[i] = sphere_hit(rays.origin(i), rays.dir(i), rays.t[i], rays.sphere[i]);
            found[i] = true;
        }
}

bool EmbreeScene::intersect(const Vec3& origin, const Vec3& dir, float tmax,
                            Hit& hit) const {
    RTCIntersectContext context = incoherent_context();
    RTCRayHit rh;
    rh.ray = single_ray(origin, dir, tmax);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &context, &rh);
    const bool mesh = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    if (mesh)
        hit = to_hit(rh.ray.tfar, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v,
                     Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
    return nearer_sphere(origin, dir, mesh ? rh.ray.tfar : tmax, hit) || mesh;
}

bool EmbreeScene::occluded(const Vec3& origin, const Vec3& dir, float tmax) const {
    if (sphere_blocks(origin, dir, tmax)) return true;
    RTCIntersectContext context = incoherent_context();
    RTCRay ray = single_ray(origin, dir, tmax);
    rtcOccluded1(scene_, &context, &ray);
    // Embree marks an occluded ray by setting tfar to -inf.
    return ray.tfar < 0.0f;
}

}  // namespace aliquot
