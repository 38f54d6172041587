#include "submitted_scenes.h"

namespace aliquot {

void SubmittedScenes::keep(const std::string& hash, const std::string& json) {
    std::lock_guard lock(mutex_);
    Scene& scene = scenes_[hash];
    if (scene.renders++ == 0) scene.json = json;
}

void SubmittedScenes::drop(const std::string& hash) {
    std::lock_guard lock(mutex_);
    const auto it = scenes_.find(hash);
    // Workers still tracing it fetch it from the store.
    if (it != scenes_.end() && --it->second.renders == 0) scenes_.erase(it);
}

std::optional<std::string> SubmittedScenes::find(const std::string& hash) const {
    std::lock_guard lock(mutex_);
    const auto it = scenes_.find(hash);
    if (it == scenes_.end()) return std::nullopt;
    return it->second.json;
}

size_t SubmittedScenes::size() const {
    std::lock_guard lock(mutex_);
    return scenes_.size();
}

}  // namespace aliquot
