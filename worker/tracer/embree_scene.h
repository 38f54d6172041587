// EmbreeScene: the one RAII wrapper around Embree 3. Nothing else includes rtcore.h.
#pragma once

#include <cstdint>
#include <vector>

#include "scene.h"
#include "sphere_lanes.h"
#include "vec3.h"

struct RTCDeviceTy;
struct RTCSceneTy;

namespace aliquot {

struct Hit {
    float t = 0;
    Vec3 ng;               // geometric normal, unit length, as the geometry defines it
    uint32_t geom_id = 0;  // mesh index, or EmbreeScene::sphere_geometry() for spheres
    uint32_t prim_id = 0;  // triangle index within the mesh, or sphere index
};

// Sets flush-to-zero / denormals-are-zero for the calling thread: Embree's traversal is
// slow on denormals. Every thread that traces calls it first.
void enable_flush_to_zero();

// Whether the mesh is made only of triangle pairs (a0, a1, a2), (a0, a2, b2), as the
// loader makes rectangles and cubes, so Embree may trace it as quads.
bool pairs_into_quads(const TriangleMesh& mesh);

// Whether the scene is only small meshes, which Embree's two-level BVH traces fastest.
bool two_level_bvh(const Scene& scene);

class EmbreeScene {
public:
    explicit EmbreeScene(const Scene& scene);
    ~EmbreeScene();
    EmbreeScene(const EmbreeScene&) = delete;
    EmbreeScene& operator=(const EmbreeScene&) = delete;

    // Closest hit along origin + t*dir for t in (0, tmax]. `dir` need not be unit length.
    bool intersect(const Vec3& origin, const Vec3& dir, float tmax, Hit& hit) const;
    // Closest hits of up to kPacket rays from one origin (a pixel's camera rays) in one
    // Embree packet query, several times faster than one query per ray for such coherent
    // rays. found[i] says whether ray i hit; hits[i] is valid only then. Embree's packet
    // kernel may round a hit differently from its single-ray kernel, and a ray's result
    // may depend on the packet it travels in: callers make packets from what the render
    // fixes.
    static constexpr int kPacket = 16;
    void intersect_packet(const Vec3& origin, const Vec3* dirs, int count, Hit* hits,
                          bool* found) const;
    // The same for rays from their own origins (a batch of paths' next bounces);
    // `coherent` is Embree's hint that the rays travel together.
    void intersect_packet(const Vec3* origins, const Vec3* dirs, int count, Hit* hits,
                          bool* found, bool coherent = false) const;
    // occluded() for up to kPacket rays in one packet query: shadow rays toward the light
    // from a batch of paths, which trace ~1.8x faster so (bench/embree_limits).
    void occluded_packet(const Vec3* origins, const Vec3* dirs, const float* tmax,
                         int count, bool* occluded) const;
    // The same queries for rays already in lanes (a batch's bounces and shadow rays),
    // each looking as far as rays.t[i] (intersect_lanes: to infinity). They use the
    // lanes' t and sphere as scratch.
    void intersect_lanes(RayLanes& rays, int count, Hit* hits, bool* found,
                         bool coherent = false) const;
    void occluded_lanes(RayLanes& rays, int count, bool* occluded) const;
    // Whether anything lies along origin + t*dir for t in (0, tmax).
    bool occluded(const Vec3& origin, const Vec3& dir, float tmax) const;

    uint32_t sphere_geometry() const { return sphere_geom_id_; }
    // Spheres a scene may have and still have them tested in our own code rather than
    // Embree's BVH (the constructor says why).
    static constexpr size_t kOwnSpheres = 16;
    // The Embree scene itself, for bench/embree_limits alone: it times Embree's packet
    // and stream queries on this very BVH, which the tracer does not use.
    RTCSceneTy* embree_handle() const { return scene_; }

private:
    // Our Hit from Embree's: a mesh's unit normal made at load by triangle (Embree's Ng
    // has its direction, unnormalised); a sphere's from Embree's Ng.
    Hit to_hit(float t, uint32_t geom, uint32_t prim, float u, float v,
               const Vec3& embree_ng) const;
    // Replaces `hit` by the nearest sphere along the ray nearer than `tmax` (the mesh
    // hit's t, or the query's bound); returns whether one was.
    bool nearer_sphere(const Vec3& origin, const Vec3& dir, float tmax, Hit& hit) const;
    bool sphere_blocks(const Vec3& origin, const Vec3& dir, float tmax) const;
    // The hit of the ray on sphere `sphere` at t.
    Hit sphere_hit(const Vec3& origin, const Vec3& dir, float t, int sphere) const;

    RTCDeviceTy* device_ = nullptr;
    RTCSceneTy* scene_ = nullptr;
    uint32_t sphere_geom_id_ = ~0u;  // one past the meshes' ids
    // Traced in our own code, not as Embree primitives (sphere_hit.h says why); empty
    // when the scene has more than kOwnSpheres, which Embree then traces.
    std::vector<Sphere> spheres_;
    struct MeshInfo {
        bool quads = false;         // traced as quads (see pairs_into_quads)
        std::vector<Vec3> normals;  // by triangle: unit geometric normal
    };
    std::vector<MeshInfo> meshes_;  // by mesh index (= Embree geometry id)
};

}  // namespace aliquot
