// Wavefront OBJ: just the vertex positions and faces a scene's triangle mesh needs.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace aliquot {

struct ObjMesh {
    // Doubles, exactly as read from the text, so that a scene with the mesh inlined as
    // JSON numbers converts to the same floats as the scene that reads the file.
    std::vector<std::array<double, 3>> positions;
    std::vector<std::array<uint32_t, 3>> triangles;
};

// Reads `v` and `f` lines (polygons fan-triangulated; `i`, `i/t`, `i//n`, `i/t/n` and
// negative indices); every other line is ignored. Throws SceneError "ORIGIN:LINE:
// message".
ObjMesh parse_obj(std::string_view text, const std::string& origin);

// The same for a file; the origin in messages is the path as given.
ObjMesh load_obj(const std::filesystem::path& file);

}  // namespace aliquot
