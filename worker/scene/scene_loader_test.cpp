// Scene loader: the built-in scenes' geometry, the format's rules, and one test per
// mistake.
#include "scene_loader.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

namespace aliquot {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const std::string kOrigin = "scenes/x.json";

// The smallest valid scene; each error test breaks one thing in it.
json minimal_scene() {
    return json::parse(R"({
        "camera": {"position": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0],
                   "fov": 40},
        "materials": {"white": {"type": "diffuse", "reflectance": [0.8, 0.8, 0.8]}},
        "shapes": [{"type": "rectangle", "material": "white", "emission": [1, 1, 1]}]
    })");
}

json with_shape(const char* shape_json) {
    json doc = minimal_scene();
    doc["shapes"].push_back(json::parse(shape_json));
    return doc;
}

Scene parse(const json& doc) { return parse_scene(doc.dump(), kOrigin, "."); }

std::string error_of_text(std::string_view text) {
    try {
        parse_scene(text, kOrigin, ".");
    } catch (const SceneError& e) {
        return e.what();
    }
    return "no error";
}

std::string error_of(const json& doc) { return error_of_text(doc.dump()); }

template <typename F>
std::string error_of_call(F&& f) {
    try {
        f();
    } catch (const SceneError& e) {
        return e.what();
    }
    return "no error";
}

Vec3 normal_of(const TriangleMesh& m, size_t t) {
    const auto& tri = m.triangles[t];
    const Vec3 &a = m.positions[tri[0]], &b = m.positions[tri[1]],
               &c = m.positions[tri[2]];
    return normalize(cross(b - a, c - a));
}

Vec3 triangle_centroid(const TriangleMesh& m, size_t t) {
    const auto& tri = m.triangles[t];
    return (m.positions[tri[0]] + m.positions[tri[1]] + m.positions[tri[2]]) / 3.0f;
}

Vec3 centroid(const TriangleMesh& m) {
    Vec3 sum;
    for (const Vec3& p : m.positions) sum += p;
    return sum / float(m.positions.size());
}

float area(const TriangleMesh& m) {
    float a = 0;
    for (const auto& t : m.triangles)
        a += 0.5f * length(cross(m.positions[t[1]] - m.positions[t[0]],
                                 m.positions[t[2]] - m.positions[t[0]]));
    return a;
}

void expect_near(const Vec3& a, const Vec3& b, float eps = 1e-5f) {
    EXPECT_NEAR(a.x, b.x, eps);
    EXPECT_NEAR(a.y, b.y, eps);
    EXPECT_NEAR(a.z, b.z, eps);
}

// Bit-for-bit: the farm relies on every machine building the same scene from the same
// text.
void expect_identical(const Scene& a, const Scene& b) {
    EXPECT_EQ(a.camera.position, b.camera.position);
    EXPECT_EQ(a.camera.target, b.camera.target);
    EXPECT_EQ(a.camera.up, b.camera.up);
    EXPECT_EQ(a.camera.fov_degrees, b.camera.fov_degrees);
    EXPECT_EQ(a.max_depth, b.max_depth);
    ASSERT_EQ(a.materials.size(), b.materials.size());
    for (size_t i = 0; i < a.materials.size(); ++i) {
        EXPECT_EQ(a.materials[i].name, b.materials[i].name);
        EXPECT_EQ(a.materials[i].kind, b.materials[i].kind);
        EXPECT_EQ(a.materials[i].reflectance, b.materials[i].reflectance);
        EXPECT_EQ(a.materials[i].ior, b.materials[i].ior);
    }
    ASSERT_EQ(a.meshes.size(), b.meshes.size());
    for (size_t i = 0; i < a.meshes.size(); ++i) {
        EXPECT_EQ(a.meshes[i].positions, b.meshes[i].positions);
        EXPECT_EQ(a.meshes[i].triangles, b.meshes[i].triangles);
        EXPECT_EQ(a.meshes[i].material, b.meshes[i].material);
        EXPECT_EQ(a.meshes[i].emission, b.meshes[i].emission);
    }
    ASSERT_EQ(a.spheres.size(), b.spheres.size());
    for (size_t i = 0; i < a.spheres.size(); ++i) {
        EXPECT_EQ(a.spheres[i].center, b.spheres[i].center);
        EXPECT_EQ(a.spheres[i].radius, b.spheres[i].radius);
        EXPECT_EQ(a.spheres[i].material, b.spheres[i].material);
    }
}

const Material& material_of(const Scene& s, const TriangleMesh& m) {
    return s.materials.at(m.material);
}

// A scene file and its meshes in a fresh folder of their own.
class SceneFiles : public testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::path(testing::TempDir()) /
               ("aliquot-scene-test-" + std::to_string(::getpid()) + "-" +
                testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_ / "meshes");
    }
    void TearDown() override { fs::remove_all(dir_); }

    std::string write(const std::string& relative, const std::string& text) {
        std::ofstream(dir_ / relative, std::ios::binary) << text;
        return (dir_ / relative).string();
    }
    std::string write_scene_with_mesh_file(const std::string& file) {
        json doc = minimal_scene();
        doc["shapes"].push_back({{"type", "mesh"},
                                 {"material", "white"},
                                 {"file", file},
                                 {"transform", {{"translate", {0, 0, 1}}}}});
        return write("scene.json", doc.dump(2));
    }

    fs::path dir_;
};

const std::string kTriangleObj = "# a triangle\nv 0.1 0 0\nv 1 0 0\nv 0 0.3 0\nf 1 2 3\n";

// ---- built-in scenes -----------------------------------------------------------------

TEST(BuiltinScenes, AreTheThreeShippedScenes) {
    EXPECT_EQ(builtin_scene_names(),
              (std::vector<std::string>{"cornell-box", "cornell-caustics", "furnace"}));
    EXPECT_FALSE(builtin_scene_json("no-such-scene").has_value());
}

TEST(BuiltinScenes, EqualTheFilesInScenesFolder) {
    for (const std::string& name : builtin_scene_names()) {
        SCOPED_TRACE(name);
        const Scene builtin = load_scene(name);
        EXPECT_EQ(builtin.name, name);
        const std::string path =
            std::string(ALIQUOT_SOURCE_DIR) + "/scenes/" + name + ".json";
        const Scene file = load_scene(path);
        EXPECT_EQ(file.name, path);
        expect_identical(builtin, file);
    }
}

TEST(CornellBox, HasMitsubasCameraMaterialsAndDepth) {
    const Scene s = load_scene("cornell-box");
    EXPECT_EQ(s.camera.position, Vec3(0, 0, 3.9f));
    EXPECT_EQ(s.camera.target, Vec3(0, 0, 0));
    EXPECT_EQ(s.camera.up, Vec3(0, 1, 0));
    EXPECT_EQ(s.camera.fov_degrees, 39.3077f);
    EXPECT_EQ(s.max_depth, 8);
    ASSERT_EQ(s.meshes.size(), 8u);
    EXPECT_TRUE(s.spheres.empty());
    EXPECT_EQ(material_of(s, s.meshes[0]).reflectance,
              Vec3(0.885809f, 0.698859f, 0.666422f));
    EXPECT_EQ(material_of(s, s.meshes[3]).reflectance,
              Vec3(0.105421f, 0.37798f, 0.076425f));
    EXPECT_EQ(material_of(s, s.meshes[4]).reflectance,
              Vec3(0.570068f, 0.0430135f, 0.0443706f));
}

TEST(CornellBox, WallsSitOnTheBoxFacesAndFaceTheInterior) {
    const Scene s = load_scene("cornell-box");
    struct Wall {
        const char* name;
        Vec3 normal;  // into the box; the wall lies at -normal
        const char* material;
    };
    const Wall walls[] = {{"floor", {0, 1, 0}, "white"},
                          {"ceiling", {0, -1, 0}, "white"},
                          {"back", {0, 0, 1}, "white"},
                          {"green", {-1, 0, 0}, "green"},
                          {"red", {1, 0, 0}, "red"}};
    for (size_t i = 0; i < 5; ++i) {
        SCOPED_TRACE(walls[i].name);
        const TriangleMesh& m = s.meshes[i];
        EXPECT_EQ(material_of(s, m).name, walls[i].material);
        EXPECT_FALSE(m.is_emitter());
        EXPECT_NEAR(area(m), 4.0f, 1e-5f);
        for (const Vec3& p : m.positions)
            EXPECT_NEAR(dot(p, walls[i].normal), -1.0f, 1e-6f);
        for (size_t t = 0; t < m.triangles.size(); ++t) {
            expect_near(normal_of(m, t), walls[i].normal);
            EXPECT_GT(dot(normal_of(m, t), -triangle_centroid(m, t)), 0.0f);
        }
    }
}

TEST(CornellBox, RedWallIsOnTheCamerasLeft) {
    const Scene s = load_scene("cornell-box");
    const Vec3 forward = normalize(s.camera.target - s.camera.position);
    const Vec3 right = cross(forward, s.camera.up);
    EXPECT_LT(dot(centroid(s.meshes[4]), right), 0.0f);
    EXPECT_EQ(material_of(s, s.meshes[4]).name, "red");
}

TEST(CornellBox, CubesHaveOutwardNormalsAndTheirTransforms) {
    const Scene s = load_scene("cornell-box");
    const struct {
        Vec3 center;
        float volume;
    } cubes[] = {{{0.335f, -0.7f, 0.38f}, 8 * 0.3f * 0.3f * 0.3f},
                 {{-0.33f, -0.4f, -0.28f}, 8 * 0.3f * 0.61f * 0.3f}};
    for (size_t i = 0; i < 2; ++i) {
        const TriangleMesh& m = s.meshes[5 + i];
        ASSERT_EQ(m.triangles.size(), 12u);
        expect_near(centroid(m), cubes[i].center);
        // Divergence theorem: sum of (centroid . normal) * area / 3 over faces is the
        // volume.
        float volume = 0;
        for (size_t t = 0; t < m.triangles.size(); ++t) {
            const Vec3 n = normal_of(m, t);
            EXPECT_GT(dot(n, triangle_centroid(m, t) - centroid(m)), 0.0f);
            const auto& tri = m.triangles[t];
            const float a =
                0.5f * length(cross(m.positions[tri[1]] - m.positions[tri[0]],
                                    m.positions[tri[2]] - m.positions[tri[0]]));
            volume += dot(triangle_centroid(m, t), n) * a / 3;
        }
        EXPECT_NEAR(volume, cubes[i].volume, 1e-5f);
    }
}

TEST(CornellBox, LightIsTheOnlyEmitterAndPointsDown) {
    const Scene s = load_scene("cornell-box");
    for (size_t i = 0; i < 7; ++i) EXPECT_FALSE(s.meshes[i].is_emitter());
    const TriangleMesh& light = s.meshes[7];
    EXPECT_EQ(light.emission, Vec3(18.387f, 13.9873f, 6.75357f));
    EXPECT_EQ(material_of(s, light).name, "white");
    EXPECT_NEAR(area(light), 0.46f * 0.38f, 1e-6f);
    expect_near(centroid(light), {0, 0.99f, 0.01f});
    for (size_t t = 0; t < light.triangles.size(); ++t)
        expect_near(normal_of(light, t), {0, -1, 0});
}

TEST(CornellCaustics, SwapsCubesForGlassAndMirrorSpheresAndKeepsLightPower) {
    const Scene box = load_scene("cornell-box");
    const Scene s = load_scene("cornell-caustics");
    ASSERT_EQ(s.meshes.size(), 6u);
    ASSERT_EQ(s.spheres.size(), 2u);
    EXPECT_EQ(s.materials.at(s.spheres[0].material).kind, Material::Kind::Dielectric);
    EXPECT_EQ(s.materials.at(s.spheres[0].material).ior, 1.5f);
    EXPECT_EQ(s.materials.at(s.spheres[1].material).kind, Material::Kind::Mirror);
    EXPECT_EQ(s.materials.at(s.spheres[1].material).reflectance, Vec3(1.0f));
    for (const Sphere& sphere : s.spheres) {  // inside the box, resting on the floor
        EXPECT_NEAR(sphere.center.y - sphere.radius, -1.0f, 1e-6f);
        EXPECT_LE(std::abs(sphere.center.x) + sphere.radius, 1.0f);
        EXPECT_LE(std::abs(sphere.center.z) + sphere.radius, 1.0f);
    }
    const TriangleMesh& light = s.meshes[5];
    const TriangleMesh& box_light = box.meshes[7];
    EXPECT_NEAR(area(light), area(box_light) / 4, 1e-6f);
    const Vec3 power = light.emission * area(light),
               box_power = box_light.emission * area(box_light);
    expect_near(power, box_power, 1e-4f);
    for (size_t i = 0; i < 5; ++i)
        EXPECT_EQ(s.meshes[i].positions, box.meshes[i].positions);
}

TEST(Furnace, IsAClosedBoxOfInwardEmittersAroundTheCamera) {
    const Scene s = load_scene("furnace");
    ASSERT_EQ(s.meshes.size(), 6u);
    EXPECT_TRUE(s.spheres.empty());
    EXPECT_EQ(s.max_depth, 8);
    Vec3 normal_sum;
    for (const TriangleMesh& m : s.meshes) {
        EXPECT_EQ(m.emission, Vec3(1.0f));
        EXPECT_EQ(material_of(s, m).kind, Material::Kind::Diffuse);
        EXPECT_EQ(material_of(s, m).reflectance, Vec3(0.5f));
        EXPECT_NEAR(area(m), 4.0f, 1e-5f);
        const Vec3 n = normal_of(m, 0);
        normal_sum += n;
        EXPECT_NEAR(dot(n, -centroid(m)), 1.0f,
                    1e-6f);  // faces the centre, from distance 1
        EXPECT_GT(dot(n, s.camera.position - centroid(m)), 0.0f);
        for (const Vec3& p :
             m.positions)  // corners exactly on the box, so no gaps at edges
            for (float c : {p.x, p.y, p.z}) EXPECT_EQ(std::abs(c), 1.0f);
    }
    expect_near(normal_sum, {0, 0, 0});  // six different faces
    EXPECT_GT(std::abs(s.camera.position.z), 0.0f);
    EXPECT_LT(std::abs(s.camera.position.z), 1.0f);
}

// ---- the format ----------------------------------------------------------------------

TEST(SceneLoader, AppliesScaleThenRotateThenTranslate) {
    const Scene s = parse(with_shape(R"({"type": "rectangle", "material": "white",
        "transform": {"translate": [1, 2, 3], "rotate": ["z", 90],
                      "scale": [2, 1, 1]}})"));
    // Corner (1, -1, 0): scaled (2, -1, 0), rotated (1, 2, 0), translated (2, 4, 3).
    expect_near(s.meshes[1].positions[1], {2, 4, 3});
}

TEST(SceneLoader, ComposesArrayTransformsFirstElementOutermost) {
    const Scene object_form = parse(with_shape(R"({"type": "cube", "material": "white",
        "transform": {"translate": [1, 2, 3], "rotate": [[1, 1, 0], 30],
                      "scale": [2, 1, 3]}})"));
    const Scene array_form = parse(with_shape(R"({"type": "cube", "material": "white",
        "transform": [{"translate": [1, 2, 3]}, {"rotate": [[1, 1, 0], 30]},
                      {"scale": [2, 1, 3]}]})"));
    const Scene reversed = parse(with_shape(R"({"type": "cube", "material": "white",
        "transform": [{"scale": [2, 1, 3]}, {"rotate": [[1, 1, 0], 30]},
                      {"translate": [1, 2, 3]}]})"));
    EXPECT_EQ(object_form.meshes[1].positions, array_form.meshes[1].positions);
    EXPECT_NE(object_form.meshes[1].positions, reversed.meshes[1].positions);
}

TEST(SceneLoader, RectangleFrontFollowsTheRotatedZAxis) {
    const Scene s = parse(with_shape(R"({"type": "rectangle", "material": "white",
        "transform": {"rotate": ["x", 90]}})"));
    for (size_t t = 0; t < 2; ++t) expect_near(normal_of(s.meshes[1], t), {0, -1, 0});
}

TEST(SceneLoader, MirroringScaleKeepsFrontsAndOutsides) {
    const Scene s = parse(with_shape(R"({"type": "rectangle", "material": "white",
        "transform": {"scale": [-1, 1, 1]}})"));
    for (size_t t = 0; t < 2; ++t) expect_near(normal_of(s.meshes[1], t), {0, 0, 1});
    const Scene c = parse(with_shape(R"({"type": "cube", "material": "white",
        "transform": {"translate": [0, 0, -5], "scale": [1, -2, 1]}})"));
    const TriangleMesh& cube = c.meshes[1];
    for (size_t t = 0; t < cube.triangles.size(); ++t)
        EXPECT_GT(dot(normal_of(cube, t), triangle_centroid(cube, t) - centroid(cube)),
                  0.0f);
}

TEST(SceneLoader, SphereTransformMovesCentreAndScalesRadius) {
    const Scene s = parse(with_shape(R"({"type": "sphere", "material": "white",
        "center": [1, 0, 0], "radius": 0.5,
        "transform": {"translate": [0, 1, 0], "rotate": ["z", 90], "scale": 2}})"));
    ASSERT_EQ(s.spheres.size(), 1u);
    expect_near(s.spheres[0].center, {0, 3, 0});
    EXPECT_NEAR(s.spheres[0].radius, 1.0f, 1e-6f);
}

TEST(SceneLoader, UsesMitsubaDefaults) {
    json doc = minimal_scene();
    doc["materials"]["plain"] = {{"type", "diffuse"}};
    doc["materials"]["mirror"] = {{"type", "mirror"}};
    doc["materials"]["glass"] = {{"type", "dielectric"}};
    doc["shapes"].push_back({{"type", "sphere"}, {"material", "glass"}});
    const Scene s = parse(doc);
    EXPECT_EQ(s.max_depth, 8);
    EXPECT_EQ(s.spheres[0].center, Vec3(0, 0, 0));
    EXPECT_EQ(s.spheres[0].radius, 1.0f);
    for (const Material& m : s.materials) {
        if (m.name == "plain") {
            EXPECT_EQ(m.reflectance, Vec3(0.5f));
        } else if (m.name == "mirror") {
            EXPECT_EQ(m.reflectance, Vec3(1.0f));
        } else if (m.name == "glass") {
            EXPECT_EQ(m.ior, 1.5f);
        }
    }
}

TEST(SceneLoader, AcceptsOneNumberForAGreyColour) {
    json doc = minimal_scene();
    doc["materials"]["white"]["reflectance"] = 0.25;
    doc["shapes"][0]["emission"] = 3;
    const Scene s = parse(doc);
    EXPECT_EQ(s.materials[0].reflectance, Vec3(0.25f));
    EXPECT_EQ(s.meshes[0].emission, Vec3(3.0f));
}

TEST(SceneLoader, ResolvesMaterialNamesToIndices) {
    json doc = minimal_scene();
    doc["materials"]["red"] = {{"type", "diffuse"}, {"reflectance", {0.5, 0, 0}}};
    doc["shapes"].push_back({{"type", "cube"}, {"material", "red"}});
    const Scene s = parse(doc);
    EXPECT_EQ(s.materials.at(s.meshes[1].material).name, "red");
    EXPECT_EQ(s.materials.at(s.meshes[0].material).name, "white");
}

TEST(SceneLoader, TransformsInlineMeshes) {
    const Scene s = parse(with_shape(R"({"type": "mesh", "material": "white",
        "positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]],
        "transform": {"translate": [0, 0, 2]}})"));
    EXPECT_EQ(s.meshes[1].positions[1], Vec3(1, 0, 2));
    EXPECT_EQ(s.meshes[1].triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
}

TEST_F(SceneFiles, MeshFilesResolveAgainstTheSceneFolder) {
    write("meshes/tri.obj", kTriangleObj);
    const Scene s = load_scene(write_scene_with_mesh_file("meshes/tri.obj"));
    ASSERT_EQ(s.meshes.size(), 2u);
    EXPECT_EQ(s.meshes[1].positions[2], Vec3(0, 0.3f, 1));
}

TEST_F(SceneFiles, LoadsAnExistingFileWithoutJsonExtension) {
    json doc = minimal_scene();
    const std::string path = write("scene.txt", doc.dump());
    EXPECT_EQ(load_scene(path).meshes.size(), 1u);
}

TEST_F(SceneFiles, SelfContainedJsonInlinesMeshFilesAndReproducesTheScene) {
    write("meshes/tri.obj", kTriangleObj);
    const std::string path = write_scene_with_mesh_file("meshes/tri.obj");
    const std::string text = self_contained_scene_json(path);
    const json doc = json::parse(text);
    const json& mesh = doc["shapes"][1];
    EXPECT_FALSE(mesh.contains("file"));
    EXPECT_EQ(mesh["positions"],
              json::parse("[[0.1, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.3, 0.0]]"));
    EXPECT_EQ(mesh["triangles"], json::parse("[[0, 1, 2]]"));
    EXPECT_EQ(mesh["transform"], json::parse(R"({"translate": [0, 0, 1]})"));
    // Another machine has the text only: no base folder, no mesh file.
    expect_identical(parse_scene(text, "sent", "/nonexistent"), load_scene(path));
}

TEST_F(SceneFiles, SelfContainedJsonIsCompactSortedAndDeterministic) {
    write("meshes/tri.obj", kTriangleObj);
    const std::string path = write_scene_with_mesh_file("meshes/tri.obj");
    const std::string text = self_contained_scene_json(path);
    EXPECT_EQ(text, self_contained_scene_json(path));
    EXPECT_EQ(text.find('\n'), std::string::npos);
    EXPECT_EQ(text, json::parse(text).dump());
    EXPECT_LT(text.find("\"camera\""), text.find("\"materials\""));
    EXPECT_LT(text.find("\"materials\""), text.find("\"shapes\""));
}

TEST(SceneLoader, SelfContainedJsonOfABuiltinReproducesIt) {
    for (const std::string& name : builtin_scene_names()) {
        SCOPED_TRACE(name);
        expect_identical(parse_scene(self_contained_scene_json(name), "sent", "."),
                         load_scene(name));
    }
}

// ---- mistakes: each names the file, the JSON path and what was expected --------------

TEST(SceneLoader, ReportsJsonSyntaxErrorWithLineAndColumn) {
    EXPECT_EQ(error_of_text("{\n  \"camera\": ,\n}").substr(0, 50),
              "scenes/x.json: invalid JSON at line 2, column 13: ");
}

TEST(SceneLoader, ReportsNumberTooLargeForJson) {
    EXPECT_EQ(error_of_text(R"({"max_depth": 1e999})"),
              "scenes/x.json: invalid JSON: number overflow parsing '1e999'");
}

TEST(SceneLoader, ReportsMissingFile) {
    EXPECT_EQ(error_of_call([] { load_scene("no/such/scene.json"); }),
              "no/such/scene.json: cannot open file");
}

TEST(SceneLoader, ListsBuiltinsForUnknownSceneName) {
    EXPECT_EQ(
        error_of_call([] { load_scene("cornel-box"); }),
        "unknown scene \"cornel-box\" (built-in scenes: cornell-box, cornell-caustics, "
        "furnace; or a path to a .json file)");
}

TEST(SceneLoader, RejectsRootThatIsNotAnObject) {
    EXPECT_EQ(error_of_text("[]"),
              "scenes/x.json: /: expected an object with camera, materials and shapes");
}

TEST(SceneLoader, RejectsUnknownKey) {
    json doc = minimal_scene();
    doc["shape"] = json::array();
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /shape: unknown key (expected description, camera, "
              "max_depth, materials, shapes)");
}

TEST(SceneLoader, RejectsDuplicateKey) {
    EXPECT_EQ(error_of_text(R"({"shapes": [{}, {"type": "cube", "type": "sphere"}]})"),
              "scenes/x.json: /shapes/1: duplicate key \"type\"");
}

TEST(SceneLoader, NamesMissingRequiredKey) {
    json doc = minimal_scene();
    doc["camera"].erase("fov");
    EXPECT_EQ(error_of(doc), "scenes/x.json: /camera: missing key \"fov\"");
}

TEST(SceneLoader, RejectsValueOfTheWrongShape) {
    json doc = minimal_scene();
    doc["camera"]["position"] = {0, 3};
    EXPECT_EQ(error_of(doc), "scenes/x.json: /camera/position: expected [x, y, z]");
}

TEST(SceneLoader, RejectsNumberTooLargeForFloat) {
    json doc = minimal_scene();
    doc["camera"]["position"] = {0, 1e300, 3};
    EXPECT_EQ(error_of(doc), "scenes/x.json: /camera/position: expected [x, y, z]");
}

TEST(SceneLoader, RejectsFovOutsideOpenRange) {
    json doc = minimal_scene();
    doc["camera"]["fov"] = 180;
    EXPECT_EQ(error_of(doc), "scenes/x.json: /camera/fov: expected a number in (0, 180)");
}

TEST(SceneLoader, RejectsCameraTargetAtItsPosition) {
    json doc = minimal_scene();
    doc["camera"]["target"] = {0, 0, 3};
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /camera/target: expected a point different from the camera "
              "position");
}

TEST(SceneLoader, RejectsUpParallelToTheView) {
    json doc = minimal_scene();
    doc["camera"]["up"] = {0, 0, -2};
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /camera/up: expected a direction not parallel to the view "
              "direction");
}

TEST(SceneLoader, RejectsMaxDepthBelowOne) {
    json doc = minimal_scene();
    doc["max_depth"] = 0;
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /max_depth: expected an integer in [1, 1000]");
}

TEST(SceneLoader, RejectsFractionalMaxDepth) {
    json doc = minimal_scene();
    doc["max_depth"] = 2.5;
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /max_depth: expected an integer in [1, 1000]");
}

TEST(SceneLoader, RejectsNegativeReflectance) {
    json doc = minimal_scene();
    doc["materials"]["white"]["reflectance"] = {0.5, -0.1, 0.5};
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /materials/white/reflectance: expected [r, g, b] or "
              "a number, each in [0, 1]");
}

TEST(SceneLoader, RejectsReflectanceAboveOne) {
    json doc = minimal_scene();
    doc["materials"]["white"]["reflectance"] = 1.5;
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /materials/white/reflectance: expected [r, g, b] or "
              "a number, each in [0, 1]");
}

TEST(SceneLoader, RejectsUnknownMaterialType) {
    json doc = minimal_scene();
    doc["materials"]["white"]["type"] = "difuse";
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /materials/white/type: unknown material type "
              "\"difuse\" (expected diffuse, mirror or dielectric)");
}

TEST(SceneLoader, RejectsKeyThatDoesNotBelongToTheMaterialType) {
    json doc = minimal_scene();
    doc["materials"]["white"]["ior"] = 1.5;
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /materials/white/ior: unknown key (expected type, "
              "reflectance)");
}

TEST(SceneLoader, RejectsNonPositiveIor) {
    json doc = minimal_scene();
    doc["materials"]["glass"] = {{"type", "dielectric"}, {"ior", 0}};
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /materials/glass/ior: expected a number > 0");
}

TEST(SceneLoader, NamesUnknownMaterialReference) {
    EXPECT_EQ(error_of(with_shape(R"({"type": "cube", "material": "whte"})")),
              "scenes/x.json: /shapes/1/material: unknown material \"whte\"");
}

TEST(SceneLoader, RejectsShapeWithoutMaterial) {
    EXPECT_EQ(error_of(with_shape(R"({"type": "cube"})")),
              "scenes/x.json: /shapes/1: missing key \"material\"");
}

TEST(SceneLoader, RejectsUnknownShapeType) {
    EXPECT_EQ(error_of(with_shape(R"({"type": "cylinder", "material": "white"})")),
              "scenes/x.json: /shapes/1/type: unknown shape type \"cylinder\" (expected "
              "rectangle, cube, sphere or mesh)");
}

TEST(SceneLoader, RejectsShapesThatAreNotAnArray) {
    json doc = minimal_scene();
    doc["shapes"] = doc["shapes"][0];
    EXPECT_EQ(error_of(doc), "scenes/x.json: /shapes: expected an array of shapes");
}

TEST(SceneLoader, NamesPathOfBadRotation) {
    EXPECT_EQ(error_of(with_shape(R"({"type": "cube", "material": "white",
                  "transform": {"rotate": ["y"]}})")),
              "scenes/x.json: /shapes/1/transform/rotate: expected [axis, degrees]");
}

TEST(SceneLoader, RejectsZeroLengthRotationAxis) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "cube", "material": "white",
                  "transform": {"rotate": [[0, 0, 0], 30]}})")),
        "scenes/x.json: /shapes/1/transform/rotate/0: expected \"x\", \"y\", \"z\" or a "
        "non-zero [x, y, z]");
}

TEST(SceneLoader, RejectsUnknownAxisName) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "cube", "material": "white",
                  "transform": {"rotate": ["w", 30]}})")),
        "scenes/x.json: /shapes/1/transform/rotate/0: expected \"x\", \"y\", \"z\" or a "
        "non-zero [x, y, z]");
}

TEST(SceneLoader, RejectsRotationAngleThatIsNotANumber) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "cube", "material": "white",
                  "transform": {"rotate": ["x", "90"]}})")),
        "scenes/x.json: /shapes/1/transform/rotate/1: expected a number of degrees");
}

TEST(SceneLoader, RejectsZeroScale) {
    EXPECT_EQ(error_of(with_shape(R"({"type": "cube", "material": "white",
                  "transform": {"scale": [1, 0, 1]}})")),
              "scenes/x.json: /shapes/1/transform/scale: expected a non-zero number or "
              "[x, y, z] of non-zero numbers");
}

TEST(SceneLoader, RejectsMisspeltTransformKey) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "cube", "material": "white",
                  "transform": {"rotation": ["x", 90]}})")),
        "scenes/x.json: /shapes/1/transform/rotation: unknown key (expected translate, "
        "rotate, scale)");
}

TEST(SceneLoader, RejectsTransformStepWithTwoKeys) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "cube", "material": "white",
                  "transform": [{"translate": [0, 0, 1], "scale": 2}]})")),
        "scenes/x.json: /shapes/1/transform/0: expected an object with exactly one of "
        "translate, rotate, scale");
}

TEST(SceneLoader, RejectsNonPositiveRadius) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "sphere", "material": "white", "radius": -1})")),
        "scenes/x.json: /shapes/1/radius: expected a number > 0");
}

TEST(SceneLoader, RejectsEmissionOnSphere) {
    EXPECT_EQ(error_of(with_shape(R"({"type": "sphere", "material": "white",
                  "emission": [1, 1, 1]})")),
              "scenes/x.json: /shapes/1/emission: expected no emission on a sphere "
              "(emitters are "
              "rectangles, cubes or meshes)");
}

TEST(SceneLoader, RejectsNonUniformScaleOnSphere) {
    EXPECT_EQ(error_of(with_shape(R"({"type": "sphere", "material": "white",
                  "transform": {"rotate": ["z", 30], "scale": [1, 2, 1]}})")),
              "scenes/x.json: /shapes/1/transform: expected translate, rotate and "
              "uniform scale "
              "only (a sphere cannot be stretched)");
}

TEST(SceneLoader, RejectsNegativeEmission) {
    json doc = minimal_scene();
    doc["shapes"][0]["emission"] = {1, -1, 1};
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /shapes/0/emission: expected [r, g, b] or a number, "
              "each >= 0");
}

TEST(SceneLoader, RejectsSceneWithoutEmitter) {
    json doc = minimal_scene();
    doc["shapes"][0]["emission"] = {0, 0, 0};
    EXPECT_EQ(error_of(doc),
              "scenes/x.json: /shapes: expected at least one emitter (a "
              "rectangle, cube or mesh with a positive \"emission\")");
}

TEST(SceneLoader, RejectsMeshWithBothFileAndInlineData) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "mesh", "material": "white", "file": "m.obj",
                  "positions": [[0, 0, 0]]})")),
        "scenes/x.json: /shapes/1: expected either \"file\" or \"positions\" and "
        "\"triangles\"");
}

TEST(SceneLoader, RejectsTriangleIndexOutOfRange) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "mesh", "material": "white",
                  "positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                  "triangles": [[0, 1, 3]]})")),
        "scenes/x.json: /shapes/1/triangles/0: expected [i, j, k] of vertex indices in "
        "[0, 3)");
}

TEST(SceneLoader, RejectsMeshFileThatIsNotObj) {
    EXPECT_EQ(
        error_of(with_shape(R"({"type": "mesh", "material": "white", "file": "m.ply"})")),
        "scenes/x.json: /shapes/1/file: expected a path to an .obj file");
}

TEST_F(SceneFiles, NamesSceneAndMeshPathOfMissingMeshFile) {
    const std::string path = write_scene_with_mesh_file("meshes/missing.obj");
    EXPECT_EQ(error_of_call([&] { load_scene(path); }),
              path + ": /shapes/1/file: " + (dir_ / "meshes/missing.obj").string() +
                  ": cannot open file");
    EXPECT_EQ(error_of_call([&] { self_contained_scene_json(path); }),
              error_of_call([&] { load_scene(path); }));
}

TEST_F(SceneFiles, PassesOnObjErrorWithItsLine) {
    write("meshes/bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
    const std::string path = write_scene_with_mesh_file("meshes/bad.obj");
    EXPECT_EQ(error_of_call([&] { load_scene(path); }),
              path + ": /shapes/1/file: " + (dir_ / "meshes/bad.obj").string() +
                  ":3: vertex index 7 out of range (2 vertices defined so far)");
}

// ---- submitted scenes (issue 13)
// -------------------------------------------------------

std::string submitted_error_of(std::string_view text) {
    return error_of_call([&] { parse_submitted_scene(text, "r"); });
}

// A submitted scene never opens a file: not a FIFO (which would block), not /dev/zero
// (endless), not a secret; the error names the pointer and says nothing of the path.
TEST_F(SceneFiles, ASubmittedSceneWithAMeshFileIsRefusedWithoutOpeningIt) {
    const fs::path fifo = dir_ / "meshes" / "fifo.obj";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    write("meshes/secret.obj", "v 1 the_admin_password 0\n");
    const std::string expected =
        "r: /shapes/1/file: mesh files are resolved by the client; a submitted scene "
        "carries its meshes inline (\"positions\" and \"triangles\")";
    const auto start = std::chrono::steady_clock::now();
    for (const std::string& file :
         {fifo.string(), std::string("/dev/zero.obj"), std::string("/dev/zero"),
          (dir_ / "meshes/secret.obj").string(), std::string("../../etc/passwd.obj"),
          std::string("meshes/missing.obj")}) {
        json doc = minimal_scene();
        doc["shapes"].push_back(
            {{"type", "mesh"}, {"material", "white"}, {"file", file}});
        EXPECT_EQ(submitted_error_of(doc.dump()), expected) << file;
    }
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
    // The same scene with its mesh inline is accepted.
    write("meshes/m.obj", kTriangleObj);
    const std::string text =
        self_contained_scene_json(write_scene_with_mesh_file("meshes/m.obj"));
    expect_identical(parse_submitted_scene(text, "r"), parse_scene(text, "r", "."));
}

TEST(SubmittedScenes, PastTheSizeLimitAreRefusedWithTheNumbers) {
    json doc = minimal_scene();
    doc["description"] = std::string(kMaxSceneJsonBytes, 'x');
    const std::string text = doc.dump();
    EXPECT_EQ(submitted_error_of(text), "r: the scene's JSON is " +
                                            std::to_string(text.size()) +
                                            " bytes; a render carries at most " +
                                            std::to_string(kMaxSceneJsonBytes) +
                                            " (4 MiB less 64 KiB, gRPC's message limit)");
    doc["description"] = "";
    EXPECT_NO_THROW(parse_submitted_scene(doc.dump(), "r"));
}

TEST_F(SceneFiles, SelfContainedSceneJsonPastTheLimitIsRefusedOnTheClient) {
    std::string obj;
    for (int i = 0; i < 200000; ++i) obj += "v 0.123456789 0.987654321 0.555555555\n";
    obj += "f 1 2 3\n";
    write("meshes/big.obj", obj);
    const std::string path = write_scene_with_mesh_file("meshes/big.obj");
    const std::string error = error_of_call([&] { self_contained_scene_json(path); });
    EXPECT_NE(error.find(path + " (with its meshes inlined): the scene's JSON is "),
              std::string::npos)
        << error;
    EXPECT_NE(
        error.find("a render carries at most " + std::to_string(kMaxSceneJsonBytes)),
        std::string::npos)
        << error;
}

}  // namespace
}  // namespace aliquot
