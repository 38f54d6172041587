// For tests: a submitted scene's JSON with an emissive mesh of `triangles` triangles
// inline, large enough to make a parse allocate what the caller wants it to (tests of
// memory limits).
#pragma once

#include <string>

namespace aliquot::testing {

inline std::string mesh_scene_text(int triangles) {
    std::string text =
        R"({"camera": {"position": [0, 0, 3.9], "target": [0, 0, 0], "up": [0, 1, 0],)"
        R"( "fov": 39}, "materials": {"white": {"type": "diffuse", "reflectance": )"
        R"([0.5, 0.5, 0.5]}}, "shapes": [{"type": "mesh", "material": "white", )"
        R"("emission": [1, 1, 1], "positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], )"
        R"("triangles": [)";
    for (int i = 0; i < triangles; ++i) text += i ? ",[0,1,2]" : "[0,1,2]";
    return text + "]}]}";
}

}  // namespace aliquot::testing
