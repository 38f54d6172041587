// The limit, measured: raw Embree throughput on a scene's BVH (the tracer's own, built by
// EmbreeScene) for every query kind Embree 3 offers, on two ray sets with 2 threads:
//   incoherent: origins spread through the scene's bounds, directions uniform on the
//   sphere
//               (what `aliquot bench` calls raw rays);
//   ours:       the rays our path tracer casts, made by following its paths on this scene
//               (cosine-weighted bounces from diffuse surfaces, mirror and refraction
//               from specular ones, next-event shadow rays toward a point on the light,
//               Russian roulette after the fifth vertex): the bounce rays (closest hit)
//               and the shadow rays (any hit), camera rays left out.
// Closest hits: rtcIntersect1, rtcIntersect4/8/16 (packets of consecutive rays, SoA
// filling included: a tracer pays it), rtcIntersect1M (a stream, incoherent and coherent
// flags). Shadow rays: the same with rtcOccluded*. Rays are made before the clock starts;
// each measurement is the best of 3 passes. One JSON object per line.
//
// Usage: embree_limits [scene] [paths]   (defaults: cornell-box 262144)
#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "camera_model.h"
#include "embree_scene.h"
#include "incoherent_rays.h"
#include "light_sampler.h"
#include "sampler.h"
#include "scene_loader.h"
#include "warp.h"

using namespace aliquot;

namespace {

struct Ray {
    Vec3 origin, dir;
    float tmax;
};

struct RaySets {
    std::vector<Ray> closest, shadow;
};

const Material& material_of(const Scene& scene, const EmbreeScene& embree,
                            const Hit& hit) {
    if (hit.geom_id == embree.sphere_geometry())
        return scene.materials[scene.spheres[hit.prim_id].material];
    return scene.materials[scene.meshes[hit.geom_id].material];
}

// Follows `paths` paths through the scene as the path tracer does and records the rays
// it would cast after the camera ray.
RaySets our_rays(const Scene& scene, const EmbreeScene& embree, size_t paths) {
    const CameraModel camera(scene.camera, 256, 256);
    const LightSampler lights(scene);
    RaySets out;
    constexpr float kInf = std::numeric_limits<float>::infinity();
    for (size_t i = 0; i < paths; ++i) {
        SampleRng rng(7, uint32_t(i % 256), uint32_t(i / 256 % 256), i);
        Vec3 o = camera.origin();
        Vec3 d = camera.direction(256 * rng.next_float(), 256 * rng.next_float());
        Hit hit;
        if (!embree.intersect(o, d, kInf, hit)) continue;
        Vec3 beta(1.0f);
        for (int depth = 0; depth + 1 < scene.max_depth; ++depth) {
            const Vec3 p = o + d * hit.t;
            const bool front = dot(d, hit.ng) < 0;
            const Vec3 n = front ? hit.ng : -hit.ng;
            const float eps =
                1e-4f * std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z), 1.0f});
            const Material& mat = material_of(scene, embree, hit);
            Vec3 wo;
            if (mat.kind == Material::Kind::Diffuse) {
                if (!lights.empty()) {
                    const LightSample ls = lights.sample(
                        rng.next_float(), rng.next_float(), rng.next_float());
                    Vec3 to = ls.position - p;
                    const float dist = std::sqrt(dot(to, to));
                    to = to / dist;
                    if (-dot(to, ls.normal) > 0 && dot(to, n) > 0)
                        out.shadow.push_back({p + n * eps, to, dist * (1.0f - 1e-3f)});
                }
                wo = cosine_hemisphere(n, rng.next_float(), rng.next_float());
                beta *= mat.reflectance;
            } else if (mat.kind == Material::Kind::Mirror || rng.next_float() < 0.1f) {
                wo = d - n * (2.0f * dot(d, n));  // mirror, or a dielectric's reflection
            } else {
                wo = d;  // a refraction leaves through the other side: close enough here
            }
            if (depth + 1 >= 5) {
                const float q = std::min(std::max({beta.x, beta.y, beta.z}), 0.95f);
                if (!(rng.next_float() < q)) break;
                beta *= 1.0f / q;
            }
            const bool through = dot(wo, n) < 0;
            o = p + (through ? -n : n) * eps;
            d = wo;
            out.closest.push_back({o, d, kInf});
            if (!embree.intersect(o, d, kInf, hit)) break;
        }
    }
    return out;
}

// incoherent_rays.h's rays, which `aliquot bench` traces too, with no distance limit.
std::vector<Ray> incoherent(const Scene& scene, size_t count) {
    std::vector<Ray> rays;
    rays.reserve(count);
    for (const RawRay& r : incoherent_rays(scene, count))
        rays.push_back({r.origin, r.dir, std::numeric_limits<float>::infinity()});
    return rays;
}

void fill(RTCRay& r, const Ray& in) {
    r.org_x = in.origin.x;
    r.org_y = in.origin.y;
    r.org_z = in.origin.z;
    r.dir_x = in.dir.x;
    r.dir_y = in.dir.y;
    r.dir_z = in.dir.z;
    r.tnear = 0;
    r.tfar = in.tmax;
    r.time = 0;
    r.mask = ~0u;
    r.id = 0;
    r.flags = 0;
}

// Packets of N consecutive rays in SoA layout (RTCRayHitN / RTCRayN of width N).
template <int N, typename RayHitN, typename RayN>
struct Packet {
    static void fill_soa(RayN& r, int lane, const Ray& in) {
        r.org_x[lane] = in.origin.x;
        r.org_y[lane] = in.origin.y;
        r.org_z[lane] = in.origin.z;
        r.dir_x[lane] = in.dir.x;
        r.dir_y[lane] = in.dir.y;
        r.dir_z[lane] = in.dir.z;
        r.tnear[lane] = 0;
        r.tfar[lane] = in.tmax;
        r.time[lane] = 0;
        r.mask[lane] = ~0u;
        r.id[lane] = unsigned(lane);
        r.flags[lane] = 0;
    }
    template <typename Query>
    static uint64_t run(RTCScene scene, const Ray* rays, size_t count, bool closest,
                        Query query) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        uint64_t answered = 0;
        alignas(64) int valid[N];
        alignas(64) RayHitN rh;
        for (size_t b = 0; b < count; b += N) {
            for (int l = 0; l < N; ++l) {
                const bool on = b + size_t(l) < count;
                valid[l] = on ? -1 : 0;
                fill_soa(rh.ray, l, rays[on ? b + size_t(l) : b]);
                rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
            }
            query(valid, scene, &ctx, &rh);
            for (int l = 0; l < N && b + size_t(l) < count; ++l)
                answered += closest ? rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID
                                    : rh.ray.tfar[l] < 0;
        }
        return answered;
    }
};

using Kernel = std::function<uint64_t(RTCScene, const Ray*, size_t)>;

Kernel single(bool closest) {
    return [closest](RTCScene scene, const Ray* rays, size_t count) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        uint64_t answered = 0;
        for (size_t i = 0; i < count; ++i) {
            RTCRayHit rh;
            fill(rh.ray, rays[i]);
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            if (closest) {
                rtcIntersect1(scene, &ctx, &rh);
                answered += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
            } else {
                rtcOccluded1(scene, &ctx, &rh.ray);
                answered += rh.ray.tfar < 0;
            }
        }
        return answered;
    };
}

template <int N, typename RayHitN, typename RayN>
Kernel packet(bool closest,
              void (*intersect)(const int*, RTCScene, RTCIntersectContext*, RayHitN*),
              void (*occluded)(const int*, RTCScene, RTCIntersectContext*, RayN*)) {
    return [=](RTCScene scene, const Ray* rays, size_t count) {
        return Packet<N, RayHitN, RayN>::run(
            scene, rays, count, closest,
            [&](const int* valid, RTCScene s, RTCIntersectContext* ctx, RayHitN* rh) {
                if (closest)
                    intersect(valid, s, ctx, rh);
                else
                    occluded(valid, s, ctx, &rh->ray);
            });
    };
}

Kernel stream(bool closest, bool coherent) {
    return [=](RTCScene scene, const Ray* rays, size_t count) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        ctx.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                             : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
        constexpr size_t kBatch = 256;
        std::vector<RTCRayHit> batch(kBatch);
        uint64_t answered = 0;
        for (size_t b = 0; b < count; b += kBatch) {
            const size_t n = std::min(kBatch, count - b);
            for (size_t i = 0; i < n; ++i) {
                fill(batch[i].ray, rays[b + i]);
                batch[i].hit.geomID = RTC_INVALID_GEOMETRY_ID;
            }
            if (closest) {
                rtcIntersect1M(scene, &ctx, batch.data(), unsigned(n), sizeof(RTCRayHit));
                for (size_t i = 0; i < n; ++i)
                    answered += batch[i].hit.geomID != RTC_INVALID_GEOMETRY_ID;
            } else {
                // RTCRayHit starts with its RTCRay: the stride skips the hits.
                rtcOccluded1M(scene, &ctx, &batch[0].ray, unsigned(n), sizeof(RTCRayHit));
                for (size_t i = 0; i < n; ++i) answered += batch[i].ray.tfar < 0;
            }
        }
        return answered;
    };
}

// Rays per second over `threads` threads (each takes a contiguous half of the rays), best
// of 3 passes; `answered` is the hits (or occlusions) of the last pass, to check kernels
// agree.
double measure(RTCScene scene, const std::vector<Ray>& rays, const Kernel& kernel,
               int threads, uint64_t& answered) {
    double best = 0;
    for (int pass = 0; pass < 3; ++pass) {
        std::atomic<uint64_t> total{0};
        const auto start = std::chrono::steady_clock::now();
        std::vector<std::thread> pool;
        for (int t = 0; t < threads; ++t)
            pool.emplace_back([&, t] {
                enable_flush_to_zero();
                const size_t begin = rays.size() * size_t(t) / size_t(threads);
                const size_t end = rays.size() * size_t(t + 1) / size_t(threads);
                total += kernel(scene, rays.data() + begin, end - begin);
            });
        for (std::thread& t : pool) t.join();
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
                .count();
        best = std::max(best, double(rays.size()) / s);
        answered = total;
    }
    return best;
}

}  // namespace

int main(int argc, char** argv) {
    const std::string name = argc > 1 ? argv[1] : "cornell-box";
    const size_t paths = argc > 2 ? size_t(std::atoll(argv[2])) : 262144;
    const Scene scene = load_scene(name);
    const EmbreeScene embree(scene);
    RTCScene handle = embree.embree_handle();
    const RaySets ours = our_rays(scene, embree, paths);
    const std::vector<Ray> incoherent_set = incoherent(scene, ours.closest.size());
    struct Query {
        const char* api;
        bool closest;
        Kernel kernel;
    };
    const std::vector<Query> queries = {
        {"rtcIntersect1", true, single(true)},
        {"rtcIntersect4", true,
         packet<4, RTCRayHit4, RTCRay4>(true, rtcIntersect4, rtcOccluded4)},
        {"rtcIntersect8", true,
         packet<8, RTCRayHit8, RTCRay8>(true, rtcIntersect8, rtcOccluded8)},
        {"rtcIntersect16", true,
         packet<16, RTCRayHit16, RTCRay16>(true, rtcIntersect16, rtcOccluded16)},
        {"rtcIntersect1M incoherent", true, stream(true, false)},
        {"rtcIntersect1M coherent", true, stream(true, true)},
        {"rtcOccluded1", false, single(false)},
        {"rtcOccluded4", false,
         packet<4, RTCRayHit4, RTCRay4>(false, rtcIntersect4, rtcOccluded4)},
        {"rtcOccluded8", false,
         packet<8, RTCRayHit8, RTCRay8>(false, rtcIntersect8, rtcOccluded8)},
        {"rtcOccluded16", false,
         packet<16, RTCRayHit16, RTCRay16>(false, rtcIntersect16, rtcOccluded16)},
        {"rtcOccluded1M incoherent", false, stream(false, false)},
        {"rtcOccluded1M coherent", false, stream(false, true)},
    };
    const int threads = 2;
    for (const Query& q : queries) {
        struct Set {
            const char* name;
            const std::vector<Ray>* rays;
        };
        for (const Set& set : {Set{"incoherent", &incoherent_set},
                               Set{q.closest ? "ours: bounce rays" : "ours: shadow rays",
                                   q.closest ? &ours.closest : &ours.shadow}}) {
            uint64_t answered = 0;
            const double rps = measure(handle, *set.rays, q.kernel, threads, answered);
            std::printf(
                "{\"scene\": \"%s\", \"rays\": \"%s\", \"api\": \"%s\", \"threads\": %d, "
                "\"count\": %zu, \"rays_per_second\": %.0f, \"answered\": %llu}\n",
                name.c_str(), set.name, q.api, threads, set.rays->size(), rps,
                (unsigned long long)answered);
            std::fflush(stdout);
        }
    }
}
