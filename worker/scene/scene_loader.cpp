// Scene loading: JSON text to a world-space Scene. Every reader knows its JSON pointer,
// so any mistake becomes "ORIGIN: /json/pointer: what was expected".
#include "scene_loader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "json_field.h"
#include "obj_loader.h"
#include "transform.h"

namespace aliquot {

// Generated from scenes/*.json by worker/scene/embed_scenes.cmake.
const std::vector<std::pair<std::string_view, std::string_view>>& builtin_scene_table();

namespace {

using json = nlohmann::json;

constexpr int kMaxDepthLimit = 1000;

// Built with append: GCC 12 warns falsely (-Wrestrict) on "literal" + std::string&&.
std::string in_quotes(std::string_view s) {
    std::string out(1, '"');
    out.append(s).push_back('"');
    return out;
}

// Scene readers fail through JsonField (a JsonError); the entry points below add the
// origin and turn it into a SceneError.
[[noreturn]] void fail_scene(const std::string& origin, const JsonError& e) {
    throw SceneError(origin + ": " + e.what());
}

// ---- values --------------------------------------------------------------------------

using FloatCheck = std::function<bool(float)>;

// The tracer works in float: a number that overflows float is as wrong as a missing one.
std::optional<float> as_float(const json& v, const FloatCheck& valid) {
    if (!v.is_number()) return std::nullopt;
    const float f = static_cast<float>(v.get<double>());
    if (!std::isfinite(f) || (valid && !valid(f))) return std::nullopt;
    return f;
}

float read_float(const JsonField& n, const std::string& expected,
                 const FloatCheck& valid = nullptr) {
    if (auto f = as_float(n.value(), valid)) return *f;
    n.fail(expected);
}

// [x, y, z], or a single number for all three when `allow_scalar` (grey colours, uniform
// scale). A bad component is reported at the array, whose form is what the message
// describes.
Vec3 read_vec3(const JsonField& n, const std::string& expected, bool allow_scalar = false,
               const FloatCheck& valid = nullptr) {
    const json& v = n.value();
    if (allow_scalar && v.is_number()) return Vec3(read_float(n, expected, valid));
    if (!v.is_array() || v.size() != 3) n.fail(expected);
    std::array<float, 3> c{};
    for (int i = 0; i < 3; ++i) {
        const auto f = as_float(v[i], valid);
        if (!f) n.fail(expected);
        c[i] = *f;
    }
    return {c[0], c[1], c[2]};
}

const std::string kPoint = "expected [x, y, z]";
const std::string kReflectance = "expected [r, g, b] or a number, each in [0, 1]";
const std::string kEmission = "expected [r, g, b] or a number, each >= 0";

Vec3 read_reflectance(const JsonField& n) {
    return read_vec3(n, kReflectance, true, [](float c) { return c >= 0 && c <= 1; });
}

// ---- transforms ----------------------------------------------------------------------

Transform read_rotate(const JsonField& n) {
    const json& v = n.value();
    if (!v.is_array() || v.size() != 2) n.fail("expected [axis, degrees]");
    const JsonField axis_node = n.at(0);
    const std::string axis_expected =
        "expected \"x\", \"y\", \"z\" or a non-zero [x, y, z]";
    Vec3 axis;
    if (axis_node.value().is_string()) {
        const std::string name = axis_node.value().get<std::string>();
        if (name == "x")
            axis = {1, 0, 0};
        else if (name == "y")
            axis = {0, 1, 0};
        else if (name == "z")
            axis = {0, 0, 1};
        else
            axis_node.fail(axis_expected);
    } else {
        axis = read_vec3(axis_node, axis_expected);
        if (!(length(axis) > 0)) axis_node.fail(axis_expected);
    }
    return Transform::rotate(axis, read_float(n.at(1), "expected a number of degrees"));
}

// One of translate / rotate / scale, by key.
Transform read_step(const JsonField& n, std::string_view key) {
    if (key == "translate") return Transform::translate(read_vec3(n, kPoint));
    if (key == "rotate") return read_rotate(n);
    // A zero scale flattens the shape and makes its normals undefined.
    return Transform::scale(
        read_vec3(n, "expected a non-zero number or [x, y, z] of non-zero numbers", true,
                  [](float s) { return s != 0; }));
}

// Object form {translate, rotate, scale} means T * R * S; array form is Mitsuba's chain
// of single steps, first element outermost.
Transform read_transform(const JsonField& n) {
    Transform m;
    if (n.value().is_object()) {
        n.allow_keys({"translate", "rotate", "scale"});
        for (std::string_view key : {"translate", "rotate", "scale"})
            if (auto step = n.find(key)) m = m * read_step(*step, key);
        return m;
    }
    const std::string expected =
        "expected an object with translate, rotate, scale, or an array of such steps";
    if (!n.value().is_array()) n.fail(expected);
    for (size_t i = 0; i < n.value().size(); ++i) {
        const JsonField step = n.at(i);
        const json& v = step.value();
        const std::string key = v.is_object() && v.size() == 1 ? v.begin().key() : "";
        if (key != "translate" && key != "rotate" && key != "scale")
            step.fail("expected an object with exactly one of translate, rotate, scale");
        m = m * read_step(*step.find(key), key);
    }
    return m;
}

double linear_determinant(const Transform& m) {
    auto a = [&](int r, int c) { return m.at(r, c); };
    return a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) -
           a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
           a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
}

// The uniform scale factor if the linear part is a rotation times a uniform scale (what
// keeps a sphere a sphere); nothing otherwise.
std::optional<double> uniform_scale(const Transform& m) {
    double col[3][3];
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) col[c][r] = m.at(r, c);
    auto dot3 = [](const double* a, const double* b) {
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    };
    const double s2 = dot3(col[0], col[0]);
    const double tolerance = 1e-6 * s2;  // rotations built from float axes are not exact
    for (int i = 0; i < 3; ++i)
        for (int j = i; j < 3; ++j)
            if (std::abs(dot3(col[i], col[j]) - (i == j ? s2 : 0.0)) > tolerance)
                return std::nullopt;
    return std::sqrt(s2);
}

// ---- shapes --------------------------------------------------------------------------

struct LocalMesh {
    std::vector<Vec3> positions;
    std::vector<std::array<uint32_t, 3>> triangles;
};

// [-1,1]^2 in z = 0; counter-clockwise seen from +z, so the geometric normal is +z.
LocalMesh rectangle_mesh() {
    return {{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, {{0, 1, 2}, {0, 2, 3}}};
}

// [-1,1]^3 as six rectangles, each counter-clockwise seen from outside.
LocalMesh cube_mesh() {
    LocalMesh mesh;
    const Vec3 e[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int k = 0; k < 3; ++k)
        for (float sign : {1.0f, -1.0f}) {
            // cross(u, v) = sign * e[k]: the outward normal of this face.
            const Vec3 n = e[k] * sign, u = e[(k + 1) % 3], v = e[(k + 2) % 3] * sign;
            const auto base = static_cast<uint32_t>(mesh.positions.size());
            for (const Vec3& p : {n - u - v, n + u - v, n + u + v, n - u + v})
                mesh.positions.push_back(p);
            mesh.triangles.push_back({base, base + 1, base + 2});
            mesh.triangles.push_back({base, base + 2, base + 3});
        }
    return mesh;
}

LocalMesh to_local_mesh(const ObjMesh& obj) {
    LocalMesh mesh;
    mesh.triangles = obj.triangles;
    for (const auto& p : obj.positions)
        mesh.positions.push_back({float(p[0]), float(p[1]), float(p[2])});
    return mesh;
}

LocalMesh read_inline_mesh(const JsonField& shape) {
    LocalMesh mesh;
    const JsonField positions = shape.require("positions");
    const JsonField triangles = shape.require("triangles");
    const std::string positions_expected = "expected a non-empty array of [x, y, z]";
    if (!positions.value().is_array() || positions.value().empty())
        positions.fail(positions_expected);
    for (size_t i = 0; i < positions.value().size(); ++i)
        mesh.positions.push_back(read_vec3(positions.at(i), kPoint));
    const size_t count = mesh.positions.size();
    if (!triangles.value().is_array() || triangles.value().empty())
        triangles.fail("expected a non-empty array of [i, j, k]");
    const std::string index_expected =
        "expected [i, j, k] of vertex indices in [0, " + std::to_string(count) + ")";
    for (size_t t = 0; t < triangles.value().size(); ++t) {
        const JsonField tri = triangles.at(t);
        const json& v = tri.value();
        if (!v.is_array() || v.size() != 3) tri.fail(index_expected);
        std::array<uint32_t, 3> indices{};
        for (int c = 0; c < 3; ++c) {
            if (!v[c].is_number_integer() || v[c].get<int64_t>() < 0 ||
                v[c].get<uint64_t>() >= count)
                tri.fail(index_expected);
            indices[c] = v[c].get<uint32_t>();
        }
        mesh.triangles.push_back(indices);
    }
    return mesh;
}

// Mesh files resolve against the scene file's folder; an OBJ error keeps its own
// file:line and is prefixed with the scene path that named the file.
ObjMesh load_mesh_file(const JsonField& file_node,
                       const std::filesystem::path& base_dir) {
    const std::string file = file_node.string("expected a path to an .obj file");
    std::string extension = std::filesystem::path(file).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (extension != ".obj") file_node.fail("expected a path to an .obj file");
    try {
        return load_obj(base_dir / file);
    } catch (const SceneError& e) {
        file_node.fail(e.what());
    }
}

void add_triangle_shape(Scene& scene, LocalMesh local, const Transform& m,
                        uint32_t material, const Vec3& emission) {
    TriangleMesh mesh;
    mesh.material = material;
    mesh.emission = emission;
    for (const Vec3& p : local.positions) mesh.positions.push_back(m.point(p));
    // A mirroring transform reverses the winding; restore it so that the front stays the
    // side the transformed normal points to (a mirrored cube still faces outward).
    if (linear_determinant(m) < 0)
        for (auto& t : local.triangles) std::swap(t[1], t[2]);
    mesh.triangles = std::move(local.triangles);
    scene.meshes.push_back(std::move(mesh));
}

class SceneBuilder {
public:
    // `submitted`: the scene came from another machine, and no file is opened for it.
    explicit SceneBuilder(const std::filesystem::path& base_dir, bool submitted = false)
        : base_dir_(base_dir), submitted_(submitted) {}

    Scene build(const JsonField& root, const std::string& origin) {
        root.expect_object("expected an object with camera, materials and shapes");
        root.allow_keys({"description", "camera", "max_depth", "materials", "shapes"});
        scene_.name = origin;
        if (auto d = root.find("description")) d->string("expected a string");
        read_camera(root.require("camera"));
        if (auto depth = root.find("max_depth")) read_max_depth(*depth);
        read_materials(root.require("materials"));
        read_shapes(root.require("shapes"));
        return std::move(scene_);
    }

private:
    void read_camera(const JsonField& n) {
        n.expect_object("expected an object with position, target, up and fov");
        n.allow_keys({"position", "target", "up", "fov"});
        Camera& c = scene_.camera;
        c.position = read_vec3(n.require("position"), kPoint);
        const JsonField target = n.require("target");
        c.target = read_vec3(target, kPoint);
        const JsonField up = n.require("up");
        c.up = read_vec3(up, kPoint);
        c.fov_degrees = read_float(n.require("fov"), "expected a number in (0, 180)",
                                   [](float f) { return f > 0 && f < 180; });
        const Vec3 view = c.target - c.position;
        if (!(length(view) > 1e-6f * std::max(1.0f, length(c.position))))
            target.fail("expected a point different from the camera position");
        if (!(length(cross(view, c.up)) > 1e-6f * length(view) * length(c.up)))
            up.fail("expected a direction not parallel to the view direction");
    }

    void read_max_depth(const JsonField& n) {
        const json& v = n.value();
        const std::string expected =
            "expected an integer in [1, " + std::to_string(kMaxDepthLimit) + "]";
        if (!v.is_number_integer() || v.get<int64_t>() < 1 ||
            v.get<int64_t>() > kMaxDepthLimit)
            n.fail(expected);
        scene_.max_depth = v.get<int>();
    }

    void read_materials(const JsonField& n) {
        n.expect_object("expected an object mapping names to materials");
        for (const auto& [name, value] : n.value().items()) {
            const JsonField m = *n.find(name);
            m.expect_object("expected an object with a \"type\"");
            const JsonField type_node = m.require("type");
            const std::string type = type_node.string("expected a material type string");
            Material material;
            material.name = name;
            if (type == "diffuse") {
                m.allow_keys({"type", "reflectance"});
                material.kind = Material::Kind::Diffuse;
                material.reflectance = Vec3(0.5f);  // Mitsuba's default
                if (auto r = m.find("reflectance"))
                    material.reflectance = read_reflectance(*r);
            } else if (type == "mirror") {
                m.allow_keys({"type", "reflectance"});
                material.kind = Material::Kind::Mirror;
                material.reflectance = Vec3(1.0f);
                if (auto r = m.find("reflectance"))
                    material.reflectance = read_reflectance(*r);
            } else if (type == "dielectric") {
                m.allow_keys({"type", "ior"});
                material.kind = Material::Kind::Dielectric;
                material.reflectance = Vec3(1.0f);
                if (auto ior = m.find("ior"))
                    material.ior = read_float(*ior, "expected a number > 0",
                                              [](float x) { return x > 0; });
            } else {
                type_node.fail("unknown material type " + in_quotes(type) +
                               " (expected diffuse, mirror or dielectric)");
            }
            material_index_[name] = static_cast<uint32_t>(scene_.materials.size());
            scene_.materials.push_back(std::move(material));
        }
    }

    uint32_t read_material_ref(const JsonField& n) {
        const std::string name = n.string("expected the name of a material");
        const auto it = material_index_.find(name);
        if (it == material_index_.end()) n.fail("unknown material " + in_quotes(name));
        return it->second;
    }

    void read_shapes(const JsonField& n) {
        if (!n.value().is_array()) n.fail("expected an array of shapes");
        for (size_t i = 0; i < n.value().size(); ++i) read_shape(n.at(i));
        const bool lit =
            std::any_of(scene_.meshes.begin(), scene_.meshes.end(),
                        [](const TriangleMesh& m) { return m.is_emitter(); });
        const std::string expected =
            "expected at least one emitter (a rectangle, cube or mesh with a positive "
            "\"emission\")";
        if (!lit) n.fail(expected);
    }

    void read_shape(const JsonField& s) {
        s.expect_object("expected an object with a \"type\"");
        const JsonField type_node = s.require("type");
        const std::string type = type_node.string("expected a shape type string");
        if (type == "rectangle" || type == "cube") {
            s.allow_keys({"type", "material", "emission", "transform"});
        } else if (type == "mesh") {
            s.allow_keys({"type", "material", "emission", "transform", "file",
                          "positions", "triangles"});
        } else if (type == "sphere") {
            const std::string no_emission =
                "expected no emission on a sphere (emitters are rectangles, cubes or "
                "meshes)";
            if (auto e = s.find("emission")) e->fail(no_emission);
            s.allow_keys({"type", "material", "center", "radius", "transform"});
        } else {
            type_node.fail("unknown shape type " + in_quotes(type) +
                           " (expected rectangle, cube, sphere or mesh)");
        }
        const uint32_t material = read_material_ref(s.require("material"));
        const auto transform_node = s.find("transform");
        const Transform m =
            transform_node ? read_transform(*transform_node) : Transform();

        if (type == "sphere") {
            Sphere sphere;
            sphere.material = material;
            if (auto c = s.find("center")) sphere.center = read_vec3(*c, kPoint);
            if (auto r = s.find("radius"))
                sphere.radius = read_float(*r, "expected a number > 0",
                                           [](float x) { return x > 0; });
            const auto scale = uniform_scale(m);
            const std::string similarity =
                "expected translate, rotate and uniform scale only (a sphere cannot be "
                "stretched)";
            if (!scale) transform_node->fail(similarity);
            sphere.center = m.point(sphere.center);
            sphere.radius = static_cast<float>(sphere.radius * *scale);
            scene_.spheres.push_back(sphere);
            return;
        }

        Vec3 emission;
        if (auto e = s.find("emission"))
            emission = read_vec3(*e, kEmission, true, [](float c) { return c >= 0; });
        LocalMesh local;
        if (type == "rectangle") {
            local = rectangle_mesh();
        } else if (type == "cube") {
            local = cube_mesh();
        } else {
            const auto file = s.find("file");
            const bool inline_data = s.find("positions") || s.find("triangles");
            if (file && submitted_)
                file->fail(
                    "mesh files are resolved by the client; a submitted scene carries "
                    "its "
                    "meshes inline (\"positions\" and \"triangles\")");
            if (file.has_value() == inline_data)
                s.fail("expected either \"file\" or \"positions\" and \"triangles\"");
            local = file ? to_local_mesh(load_mesh_file(*file, base_dir_))
                         : read_inline_mesh(s);
        }
        add_triangle_shape(scene_, std::move(local), m, material, emission);
    }

    std::filesystem::path base_dir_;
    bool submitted_ = false;
    Scene scene_;
    std::map<std::string, uint32_t> material_index_;
};

// ---- text ----------------------------------------------------------------------------

json parse_scene_json(std::string_view text, const std::string& origin) {
    try {
        return parse_json(text);
    } catch (const JsonError& e) {
        fail_scene(origin, e);
    }
}

void check_scene_size(size_t bytes, const std::string& origin) {
    if (bytes > kMaxSceneJsonBytes)
        throw SceneError(origin + ": the scene's JSON is " + std::to_string(bytes) +
                         " bytes; a render carries at most " +
                         std::to_string(kMaxSceneJsonBytes) +
                         " (4 MiB less 64 KiB, gRPC's message limit)");
}

struct SceneSource {
    std::string text;
    std::string origin;  // for messages
    std::filesystem::path base_dir;
    std::string builtin_name;  // empty for files
};

SceneSource find_scene(const std::string& name_or_file) {
    if (auto text = builtin_scene_json(name_or_file))
        return {*text, "builtin:" + name_or_file, {}, name_or_file};
    const std::filesystem::path path(name_or_file);
    if (path.extension() != ".json" && !std::filesystem::exists(path)) {
        std::string names;
        for (const auto& n : builtin_scene_names())
            names += (names.empty() ? "" : ", ") + n;
        throw SceneError("unknown scene " + in_quotes(name_or_file) +
                         " (built-in scenes: " + names + "; or a path to a .json file)");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in || std::filesystem::is_directory(path))
        throw SceneError(name_or_file + ": cannot open file");
    std::ostringstream text;
    text << in.rdbuf();
    return {text.str(), name_or_file, path.parent_path(), ""};
}

// Replaces each mesh "file" with the OBJ's raw positions and triangles; the transform
// stays. Shapes that are malformed are left alone for the scene reader to report.
void inline_mesh_files(json& doc, const SceneSource& source) {
    if (!doc.is_object() || !doc.contains("shapes") || !doc["shapes"].is_array()) return;
    json& shapes = doc["shapes"];
    for (size_t i = 0; i < shapes.size(); ++i) {
        json& shape = shapes[i];
        if (!shape.is_object() || !shape.contains("type") || shape["type"] != "mesh" ||
            !shape.contains("file") || shape.contains("positions") ||
            shape.contains("triangles"))
            continue;
        const JsonField file(shape["file"], "/shapes/" + std::to_string(i) + "/file");
        const ObjMesh mesh = load_mesh_file(file, source.base_dir);
        json positions = json::array(), triangles = json::array();
        for (const auto& p : mesh.positions) positions.push_back({p[0], p[1], p[2]});
        for (const auto& t : mesh.triangles) triangles.push_back({t[0], t[1], t[2]});
        shape.erase("file");
        shape["positions"] = std::move(positions);
        shape["triangles"] = std::move(triangles);
    }
}

}  // namespace

// The document is a JsonDocument: out of memory, a scene fails with std::bad_alloc and
// takes nothing down (a plain json's destructor could abort the process).
Scene parse_scene(std::string_view json_text, const std::string& origin,
                  const std::filesystem::path& base_dir) {
    try {
        const JsonDocument doc(json_text);
        return SceneBuilder(base_dir).build(JsonField(doc.root()), origin);
    } catch (const JsonError& e) {
        fail_scene(origin, e);
    }
}

Scene parse_submitted_scene(std::string_view json_text, const std::string& origin) {
    check_scene_size(json_text.size(), origin);
    try {
        const JsonDocument doc(json_text);
        return SceneBuilder({}, true).build(JsonField(doc.root()), origin);
    } catch (const JsonError& e) {
        fail_scene(origin, e);
    }
}

Scene load_scene(const std::string& name_or_file) {
    const SceneSource source = find_scene(name_or_file);
    Scene scene = parse_scene(source.text, source.origin, source.base_dir);
    if (!source.builtin_name.empty()) scene.name = source.builtin_name;
    return scene;
}

std::string self_contained_scene_json(const std::string& name_or_file) {
    const SceneSource source = find_scene(name_or_file);
    json doc = parse_scene_json(source.text, source.origin);
    try {
        inline_mesh_files(doc, source);
        // Validate what is sent, so that a broken scene fails here and not on every
        // worker.
        SceneBuilder(source.base_dir).build(JsonField(doc), source.origin);
    } catch (const JsonError& e) {
        fail_scene(source.origin, e);
    }
    std::string text = doc.dump();  // compact, keys sorted: the same scene, the same text
    check_scene_size(text.size(), source.origin + " (with its meshes inlined)");
    return text;
}

std::optional<std::string> builtin_scene_json(std::string_view name) {
    for (const auto& [builtin, text] : builtin_scene_table())
        if (builtin == name) return std::string(text);
    return std::nullopt;
}

std::vector<std::string> builtin_scene_names() {
    std::vector<std::string> names;
    for (const auto& entry : builtin_scene_table()) names.emplace_back(entry.first);
    std::sort(names.begin(), names.end());
    return names;
}

}  // namespace aliquot
