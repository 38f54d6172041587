#include "embree_scene.h"

#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

namespace aliquot {

namespace {

// Installed before any other call, so that no Embree call needs its own error check:
// configuration errors surface here, and construction fails below.
void on_embree_error(void*, RTCError code, const char* message) {
    std::fprintf(stderr, "aliquot: embree error %d: %s\n", int(code), message ? message : "");
}

void throw_if_failed(RTCDevice device, const char* what) {
    const RTCError err = rtcGetDeviceError(device);
    if (err != RTC_ERROR_NONE) {
        throw std::runtime_error(std::string("embree failed to ") + what + " (error " +
                                 std::to_string(int(err)) + ")");
    }
}

}  // namespace

void enable_flush_to_zero() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

EmbreeScene::EmbreeScene(const Scene& scene) {
    enable_flush_to_zero();
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("embree: cannot create a device");
    rtcSetDeviceErrorFunction(device_, on_embree_error, nullptr);
    scene_ = rtcNewScene(device_);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);

    for (const TriangleMesh& mesh : scene.meshes) {
        RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
            mesh.positions.size()));
        for (size_t i = 0; i < mesh.positions.size(); ++i) {
            v[3 * i] = mesh.positions[i].x;
            v[3 * i + 1] = mesh.positions[i].y;
            v[3 * i + 2] = mesh.positions[i].z;
        }
        auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
            mesh.triangles.size()));
        for (size_t i = 0; i < mesh.triangles.size(); ++i)
            for (int k = 0; k < 3; ++k) idx[3 * i + k] = mesh.triangles[i][k];
        rtcCommitGeometry(geom);
        rtcAttachGeometry(scene_, geom);  // ids are sequential: geom id == mesh index
        rtcReleaseGeometry(geom);
    }

    if (!scene.spheres.empty()) {
        RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
        auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float),
            scene.spheres.size()));
        for (size_t i = 0; i < scene.spheres.size(); ++i) {
            v[4 * i] = scene.spheres[i].center.x;
            v[4 * i + 1] = scene.spheres[i].center.y;
            v[4 * i + 2] = scene.spheres[i].center.z;
            v[4 * i + 3] = scene.spheres[i].radius;
        }
        rtcCommitGeometry(geom);
        sphere_geom_id_ = rtcAttachGeometry(scene_, geom);
        rtcReleaseGeometry(geom);
    }

    rtcCommitScene(scene_);
    throw_if_failed(device_, "build the scene");
}

EmbreeScene::~EmbreeScene() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
}

bool EmbreeScene::intersect(const Vec3& origin, const Vec3& dir, float tmax, Hit& hit) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    RTCRayHit rh;
    rh.ray.org_x = origin.x;
    rh.ray.org_y = origin.y;
    rh.ray.org_z = origin.z;
    rh.ray.dir_x = dir.x;
    rh.ray.dir_y = dir.y;
    rh.ray.dir_z = dir.z;
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = tmax;
    rh.ray.time = 0.0f;
    rh.ray.mask = ~0u;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    hit.t = rh.ray.tfar;
    hit.ng = normalize(Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
    hit.geom_id = rh.hit.geomID;
    hit.prim_id = rh.hit.primID;
    return true;
}

bool EmbreeScene::occluded(const Vec3& origin, const Vec3& dir, float tmax) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
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
    rtcOccluded1(scene_, &context, &ray);
    // Embree marks an occluded ray by setting tfar to -inf.
    return ray.tfar < 0.0f;
}

}  // namespace aliquot
