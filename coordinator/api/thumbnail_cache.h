#pragma once
// The renders list's thumbnails (GET /api/renders/{id}/thumbnail.png): small PNGs kept
// per render and made again only when the render has moved on, so a list of many renders
// that every open dashboard refetches costs one image copy per render per change, not per
// look.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <list>
#include <mutex>
#include <string>
#include <unordered_map>

namespace aliquot {

class ThumbnailCache {
public:
    // At most `capacity` thumbnails are kept (the least recently asked for goes first);
    // at 96 px each is a few KB.
    explicit ThumbnailCache(size_t capacity);

    // The PNG of render `id` at `version` (anything that changes when its image does:
    // samples merged, state); `make` runs, off the cache's lock, only when the kept one
    // is of another version or there is none. `make` may throw; nothing is kept then.
    std::string get(const std::string& id, const std::string& version,
                    const std::function<std::string()>& make);
    // A deleted render's thumbnail goes with it.
    void forget(const std::string& id);
    size_t size() const;
    // How many times `make` ran: what the tests count.
    uint64_t made() const;

private:
    struct Entry {
        std::string version, png;
        std::list<std::string>::iterator use;
    };
    size_t capacity_;
    mutable std::mutex mutex_;
    std::unordered_map<std::string, Entry> entries_;
    std::list<std::string> uses_;  // most recent first
    uint64_t made_ = 0;
};

}  // namespace aliquot
