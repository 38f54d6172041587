// For the api room's tests: places of a cap held without timing.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>

namespace aliquot::testing {

// Places held by requests that a test hook keeps waiting (HttpOptions::image_admitted,
// GrpcLimits::running_fetch_admitted), no timing: the first `hold` requests admitted
// wait until release(); later ones go on.
class HeldPlaces {
public:
    explicit HeldPlaces(size_t hold) : hold_(hold) {}
    std::function<void()> hook() {
        return [this] {
            std::unique_lock lock(mutex_);
            if (++admitted_ > hold_) return;
            changed_.notify_all();
            changed_.wait(lock, [&] { return released_; });
        };
    }
    // Whether `hold` requests wait (a generous deadline against a hang, not a timing
    // check).
    bool all_held() {
        std::unique_lock lock(mutex_);
        return changed_.wait_for(lock, std::chrono::seconds(30),
                                 [&] { return admitted_ >= hold_; });
    }
    void release() {
        std::lock_guard lock(mutex_);
        released_ = true;
        changed_.notify_all();
    }
    size_t admitted() {
        std::lock_guard lock(mutex_);
        return admitted_;
    }

private:
    const size_t hold_;
    std::mutex mutex_;
    std::condition_variable changed_;
    size_t admitted_ = 0;
    bool released_ = false;
};

}  // namespace aliquot::testing
