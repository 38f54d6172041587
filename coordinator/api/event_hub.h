// The HTTP server's live updates, between the one thread that publishes them and every
// event stream that sends them (http_live_updates.cpp): a ring of numbered messages, so
// that a slow stream is told to resynchronise rather than queued for without bound.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace aliquot {

// Live updates: the broadcaster publishes numbered messages, each event stream sends
// those it has not sent yet. A stream that falls further behind than the ring holds is
// told to resynchronise (fetch everything again) instead of being queued for without
// bound.
class EventHub {
public:
    void publish(std::string message) {
        {
            std::lock_guard lock(mutex_);
            ring_.emplace_back(next_++, std::move(message));
            if (ring_.size() > kRing) ring_.pop_front();
        }
        cv_.notify_all();
    }
    uint64_t next() {
        std::lock_guard lock(mutex_);
        return next_;
    }
    // Waits up to `timeout` for messages numbered `from` or later and appends them to
    // `out`, advancing `from`. Returns false once the hub has stopped.
    bool wait(uint64_t& from, std::chrono::milliseconds timeout,
              std::vector<std::string>& out, bool& missed) {
        std::unique_lock lock(mutex_);
        cv_.wait_for(lock, timeout, [&] { return stopping_ || next_ > from; });
        if (stopping_) return false;
        missed = !ring_.empty() && ring_.front().first > from;
        for (const auto& [seq, message] : ring_)
            if (seq >= from) out.push_back(message);
        from = next_;
        return true;
    }
    void stop() {
        {
            std::lock_guard lock(mutex_);
            stopping_ = true;
        }
        cv_.notify_all();
    }
    bool stopping() {
        std::lock_guard lock(mutex_);
        return stopping_;
    }
    // Sleeps `d` unless the hub stops first.
    void pause(std::chrono::milliseconds d) {
        std::unique_lock lock(mutex_);
        cv_.wait_for(lock, d, [&] { return stopping_; });
    }

private:
    static constexpr size_t kRing = 256;
    std::mutex mutex_;
    std::condition_variable cv_;
    std::deque<std::pair<uint64_t, std::string>> ring_;
    uint64_t next_ = 1;
    bool stopping_ = false;
};

}  // namespace aliquot
