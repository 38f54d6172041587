// Scene loading: the JSON scene format (docs/SCENES.md), built-in scenes, OBJ meshes.
// Every mistake becomes a SceneError that names the file, the JSON path and what was
// expected.
#pragma once

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "scene.h"

namespace aliquot {

class SceneError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Parses scene JSON. `origin` names the source in messages (a file path or
// "builtin:NAME"); relative mesh paths resolve against `base_dir`.
Scene parse_scene(std::string_view json_text, const std::string& origin,
                  const std::filesystem::path& base_dir);

// A built-in name (see builtin_scene_names) or a path to a .json file.
Scene load_scene(const std::string& name_or_file);

// The JSON text of a scene with every mesh file inlined, so that the text alone
// reproduces the scene on another machine (what the farm sends and hashes).
std::string self_contained_scene_json(const std::string& name_or_file);

std::optional<std::string> builtin_scene_json(std::string_view name);
std::vector<std::string> builtin_scene_names();

}  // namespace aliquot
