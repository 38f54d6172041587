// OBJ reader: the subset scenes use, and errors that name the file and line.
#include "obj_loader.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <filesystem>
#include <fstream>

#include "scene_loader.h"

namespace aliquot {
namespace {

using Triangle = std::array<uint32_t, 3>;

std::string error_of(std::string_view text) {
    try {
        parse_obj(text, "meshes/m.obj");
    } catch (const SceneError& e) {
        return e.what();
    }
    return "no error";
}

TEST(ObjLoader, ReadsVerticesAndTriangles) {
    const ObjMesh m = parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "m.obj");
    ASSERT_EQ(m.positions.size(), 3u);
    EXPECT_EQ(m.positions[1], (std::array<double, 3>{1, 0, 0}));
    ASSERT_EQ(m.triangles.size(), 1u);
    EXPECT_EQ(m.triangles[0], (Triangle{0, 1, 2}));
}

TEST(ObjLoader, KeepsCoordinatesExactlyAsWritten) {
    const ObjMesh m = parse_obj("v 0.1 1e-3 -2.5\nv +1 0 0\nv 0 1 0\nf 1 2 3", "m.obj");
    EXPECT_EQ(m.positions[0], (std::array<double, 3>{0.1, 1e-3, -2.5}));
    EXPECT_EQ(m.positions[1][0], 1.0);
}

TEST(ObjLoader, FanTriangulatesPolygons) {
    const ObjMesh m =
        parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 1 0\nf 1 2 3 4 5\n", "m.obj");
    ASSERT_EQ(m.triangles.size(), 3u);
    EXPECT_EQ(m.triangles[0], (Triangle{0, 1, 2}));
    EXPECT_EQ(m.triangles[1], (Triangle{0, 2, 3}));
    EXPECT_EQ(m.triangles[2], (Triangle{0, 3, 4}));
}

TEST(ObjLoader, ResolvesNegativeIndicesAgainstVerticesSoFar) {
    const ObjMesh m = parse_obj(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -1 -2\n", "m.obj");
    ASSERT_EQ(m.triangles.size(), 2u);
    EXPECT_EQ(m.triangles[0], (Triangle{0, 1, 2}));
    EXPECT_EQ(m.triangles[1], (Triangle{0, 3, 2}));
}

TEST(ObjLoader, AcceptsTextureAndNormalIndexForms) {
    const ObjMesh m = parse_obj(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
        "f 1/1 2/1 3/1\nf 1//1 2//1 3//1\nf 3/1/1 2/1/1 1/1/1\n",
        "m.obj");
    ASSERT_EQ(m.triangles.size(), 3u);
    EXPECT_EQ(m.triangles[1], (Triangle{0, 1, 2}));
    EXPECT_EQ(m.triangles[2], (Triangle{2, 1, 0}));
}

TEST(ObjLoader, IgnoresOtherLinesCommentsAndCarriageReturns) {
    const ObjMesh m = parse_obj(
        "# exported\r\nmtllib x.mtl\r\no thing\r\ng group\r\ns off\r\nusemtl red\r\n"
        "\tv 0 0 0 1   # with w\r\nv 1 0 0\r\nv 0 1 0\r\nl 1 2\r\n\r\nf 1 2 3\r\n",
        "m.obj");
    EXPECT_EQ(m.positions.size(), 3u);
    EXPECT_EQ(m.triangles.size(), 1u);
}

TEST(ObjLoader, NamesFileAndLineOfIndexOutOfRange) {
    EXPECT_EQ(error_of("v 0 0 0\nv 1 0 0\nf 1 2 3\n"),
              "meshes/m.obj:3: vertex index 3 out of range (2 vertices defined so far)");
}

TEST(ObjLoader, RejectsIndexZero) {
    EXPECT_EQ(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
              "meshes/m.obj:4: expected a vertex index (non-zero integer) as corner 1 of "
              "the face");
}

TEST(ObjLoader, RejectsFaceWithFewerThanThreeVertices) {
    EXPECT_EQ(error_of("v 0 0 0\nv 1 0 0\nf 1 2\n"),
              "meshes/m.obj:3: expected a face with at least 3 vertices");
}

TEST(ObjLoader, RejectsCoordinateThatIsNotANumber) {
    EXPECT_EQ(error_of("v 0 zero 0\n"),
              "meshes/m.obj:1: expected a finite number as coordinate 2 of the vertex");
}

// Issue 13: an error never carries the text it found (a "mesh" may be any file).
TEST(ObjLoader, ErrorsNeverQuoteTheOffendingText) {
    for (const char* text : {"v 1 the_admin_password 0\n",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 the_admin_password\n",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nf the_admin_password/x 2 3\n",
                             "v 1 2 3 the_admin_password\nv nan_admin_password 0 0\n"}) {
        const std::string error = error_of(text);
        EXPECT_EQ(error.find("admin_password"), std::string::npos) << error;
        EXPECT_NE(error.find("meshes/m.obj:"), std::string::npos) << error;
    }
}

TEST(ObjLoader, RejectsVertexWithTooFewCoordinates) {
    EXPECT_EQ(error_of("v 0 0\n"), "meshes/m.obj:1: expected \"v x y z\"");
}

TEST(ObjLoader, RejectsFileWithoutFaces) {
    EXPECT_EQ(error_of("v 0 0 0\n"), "meshes/m.obj: no faces (expected \"f\" lines)");
}

TEST(ObjLoader, ReportsMissingFile) {
    const std::filesystem::path missing =
        std::filesystem::path(testing::TempDir()) / "aliquot-no-such-dir" / "missing.obj";
    try {
        load_obj(missing);
        FAIL() << "no error";
    } catch (const SceneError& e) {
        EXPECT_EQ(std::string(e.what()), missing.string() + ": cannot open file");
    }
}

TEST(ObjLoader, ReadsAFile) {
    const std::filesystem::path file =
        std::filesystem::path(testing::TempDir()) /
        ("aliquot-obj-loader-test-" + std::to_string(::getpid()) + ".obj");
    std::ofstream(file) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    EXPECT_EQ(load_obj(file).triangles.size(), 1u);
    std::filesystem::remove(file);
}

}  // namespace
}  // namespace aliquot
