// SceneCache: scenes a worker has loaded, by content hash, each with its Embree scene
// built once and shared by all the worker's threads.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "path_tracer.h"

namespace aliquot {

struct LoadedScene {
    Scene scene;
    std::unique_ptr<PathTracer> tracer;  // refers to `scene`; LoadedScene never moves
};

class SceneCache {
public:
    using Fetch = std::function<std::optional<std::string>(const std::string& hash)>;

    // The scene for `hash`, fetching its JSON with `fetch` the first time. Throws
    // SceneError for a scene that does not parse, std::runtime_error for an unknown hash.
    std::shared_ptr<const LoadedScene> get(const std::string& hash, const Fetch& fetch);

private:
    std::mutex mutex_;
    std::map<std::string, std::shared_ptr<const LoadedScene>> scenes_;
};

}  // namespace aliquot
