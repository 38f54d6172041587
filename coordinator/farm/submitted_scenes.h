// SubmittedScenes: the scenes of the renders in memory, by content hash, for workers'
// fetch_scene; each is dropped with the last render that uses it (a scene is 1 MB or
// more, and submissions never end), and read from the store after that.
// Its own lock, a leaf (docs/FARM.md, "Locks").
#pragma once

#include <cstddef>
#include <map>
#include <mutex>
#include <optional>
#include <string>

namespace aliquot {

class SubmittedScenes {
public:
    // One more render in memory uses the scene `hash`.
    void keep(const std::string& hash, const std::string& json);
    // One render that used it left memory (or its submission failed).
    void drop(const std::string& hash);
    std::optional<std::string> find(const std::string& hash) const;
    size_t size() const;

private:
    struct Scene {
        std::string json;
        size_t renders = 0;
    };
    mutable std::mutex mutex_;
    std::map<std::string, Scene> scenes_;  // by hash
};

}  // namespace aliquot
