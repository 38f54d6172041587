#include "scene_cache.h"

#include <stdexcept>

#include "scene_loader.h"

namespace aliquot {

std::shared_ptr<const LoadedScene> SceneCache::get(const std::string& hash,
                                                   const Fetch& fetch) {
    {
        std::lock_guard lock(mutex_);
        if (auto it = scenes_.find(hash); it != scenes_.end()) return it->second;
    }
    // Fetched and built outside the lock; two threads racing build it twice, harmlessly.
    const std::optional<std::string> json = fetch(hash);
    if (!json) throw std::runtime_error("coordinator does not know scene " + hash);
    auto loaded = std::make_shared<LoadedScene>();
    loaded->scene = parse_submitted_scene(*json, "scene:" + hash);
    loaded->tracer = std::make_unique<PathTracer>(loaded->scene);
    std::lock_guard lock(mutex_);
    return scenes_.try_emplace(hash, std::move(loaded)).first->second;
}

}  // namespace aliquot
