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
// "builtin:NAME"); relative mesh paths resolve against `base_dir`. For the machine whose
// files the scene names: the CLI, tests, tools.
Scene parse_scene(std::string_view json_text, const std::string& origin,
                  const std::filesystem::path& base_dir);

// The most scene JSON a render may carry: 4 MiB less 64 KiB, so that a SubmitRequest (or
// a FetchScene answer) with it stays under gRPC's default 4 MiB receive limit, which the
// coordinator's server and the workers' channels keep. Raising one means raising the
// others (docs/SECURITY.md, "Scenes").
inline constexpr size_t kMaxSceneJsonBytes = (size_t(4) << 20) - (size_t(64) << 10);

// Parses a scene another machine sent (the coordinator's submit, a worker's fetch): the
// same format, but it never opens a file. A mesh "file" is refused (the client resolves
// meshes and sends them inline, see self_contained_scene_json), and so is text past
// kMaxSceneJsonBytes.
Scene parse_submitted_scene(std::string_view json_text, const std::string& origin);

// A built-in name (see builtin_scene_names) or a path to a .json file.
Scene load_scene(const std::string& name_or_file);

// The JSON text of a scene with every mesh file inlined, so that the text alone
// reproduces the scene on another machine (what the farm sends and hashes). Throws
// SceneError past kMaxSceneJsonBytes.
std::string self_contained_scene_json(const std::string& name_or_file);

std::optional<std::string> builtin_scene_json(std::string_view name);
std::vector<std::string> builtin_scene_names();

}  // namespace aliquot
