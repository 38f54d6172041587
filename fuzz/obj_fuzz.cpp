// Fuzzes parse_obj, the Wavefront OBJ reader behind a scene's mesh files. Its contract: a
// mesh whose triangles index its own positions, or a SceneError.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "obj_loader.h"
#include "scene_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        const aliquot::ObjMesh mesh = aliquot::parse_obj(text, "fuzz.obj");
        for (const auto& t : mesh.triangles)
            for (uint32_t i : t)
                if (i >= mesh.positions.size()) std::abort();
    } catch (const aliquot::SceneError&) {
    }
    return 0;
}
