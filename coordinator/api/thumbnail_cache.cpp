#include "thumbnail_cache.h"

namespace aliquot {

ThumbnailCache::ThumbnailCache(size_t capacity) : capacity_(capacity ? capacity : 1) {}

std::string ThumbnailCache::get(const std::string& id, const std::string& version,
                                const std::function<std::string()>& make) {
    {
        std::lock_guard lock(mutex_);
        const auto it = entries_.find(id);
        if (it != entries_.end() && it->second.version == version) {
            uses_.splice(uses_.begin(), uses_, it->second.use);
            return it->second.png;
        }
    }
    // Made off the lock: one render's image copy does not hold up other thumbnails.
    std::string png = make();
    std::lock_guard lock(mutex_);
    ++made_;
    auto it = entries_.find(id);
    if (it == entries_.end()) {
        uses_.push_front(id);
        it = entries_.emplace(id, Entry{version, png, uses_.begin()}).first;
    } else {
        it->second.version = version;
        it->second.png = png;
        uses_.splice(uses_.begin(), uses_, it->second.use);
    }
    while (entries_.size() > capacity_) {
        entries_.erase(uses_.back());
        uses_.pop_back();
    }
    return png;
}

void ThumbnailCache::forget(const std::string& id) {
    std::lock_guard lock(mutex_);
    const auto it = entries_.find(id);
    if (it == entries_.end()) return;
    uses_.erase(it->second.use);
    entries_.erase(it);
}

size_t ThumbnailCache::size() const {
    std::lock_guard lock(mutex_);
    return entries_.size();
}

uint64_t ThumbnailCache::made() const {
    std::lock_guard lock(mutex_);
    return made_;
}

}  // namespace aliquot
