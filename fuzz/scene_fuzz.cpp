// Fuzzes parse_scene, the JSON scene reader every worker and the coordinator's submit run
// on scene text from the network. Its contract: a Scene or a SceneError, nothing else.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "scene_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        // A base folder that holds no files: mesh paths reach load_obj's error path, and
        // a run never depends on what the machine happens to have.
        aliquot::parse_scene(text, "fuzz", "/nonexistent-aliquot-fuzz");
    } catch (const aliquot::SceneError&) {
    }
    return 0;
}
