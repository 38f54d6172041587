// Scene: what the tracer needs to know of a scene, already in world space.
// Every shape but the sphere becomes a triangle mesh at load time; nothing else is
// modelled.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "vec3.h"

namespace aliquot {

struct Camera {
    Vec3 position{0, 0, 1};
    Vec3 target{0, 0, 0};
    Vec3 up{0, 1, 0};
    // Field of view in degrees along the image's smaller axis (Mitsuba's fov_axis
    // "smaller").
    float fov_degrees = 40.0f;
};

struct Material {
    enum class Kind { Diffuse, Mirror, Dielectric };
    std::string name;
    Kind kind = Kind::Diffuse;
    Vec3 reflectance{0.5f, 0.5f, 0.5f};  // diffuse albedo, or mirror tint
    float ior = 1.5f;  // dielectric: interior / exterior index of refraction
};

struct TriangleMesh {
    std::vector<Vec3> positions;
    std::vector<std::array<uint32_t, 3>> triangles;
    uint32_t material = 0;
    // Radiance emitted from the front side (the side the geometric normal points to,
    // i.e. counter-clockwise winding as seen from the front). Zero: not an emitter.
    Vec3 emission{0, 0, 0};

    bool is_emitter() const { return emission.x > 0 || emission.y > 0 || emission.z > 0; }
};

struct Sphere {
    Vec3 center;
    float radius = 1.0f;
    uint32_t material = 0;
};

struct Scene {
    std::string name;  // built-in name or file path, for messages
    Camera camera;
    std::vector<Material> materials;
    std::vector<TriangleMesh> meshes;
    std::vector<Sphere> spheres;
    int max_depth = 8;  // path length in segments, counted as Mitsuba counts it
};

}  // namespace aliquot
