// Cuts a gRPC server stream whose client stops taking it. gRPC's sync ServerWriter::Write
// blocks while the stream's flow-control window is full, so a client that stops reading
// a FetchImage or Watch stream (but still answers keepalive pings) held a server thread
// and one of the stream places for as long as it liked (docs/SECURITY.md, "HTTP image
// routes" and "gRPC listener and limits"). The HTTP image routes' pace applies instead:
// each write must end within a grace and its bytes at a least rate, or the call is
// cancelled (ServerContext::TryCancel), which makes the blocked Write return false.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <map>
#include <mutex>
#include <thread>

namespace grpc {
class ServerContext;
}

namespace aliquot {

class StreamWatchdog {
public:
    using Clock = std::chrono::steady_clock;

    // A stream must be taken at `min_rate` bytes a second at least, after `grace`.
    StreamWatchdog(std::chrono::milliseconds grace, size_t min_rate);
    // Stops the watchdog's thread. No write may be watched any more.
    ~StreamWatchdog();
    StreamWatchdog(const StreamWatchdog&) = delete;
    StreamWatchdog& operator=(const StreamWatchdog&) = delete;

    // By when `bytes` sent from now must have been taken: now + grace + bytes / min_rate.
    Clock::time_point due(size_t bytes) const;

    // One write of a stream, watched while this lives: if it has not ended by `deadline`,
    // `call` is cancelled. Made before the write, destroyed right after it.
    class WatchedWrite {
    public:
        WatchedWrite(StreamWatchdog& watchdog, grpc::ServerContext& call,
                     Clock::time_point deadline);
        ~WatchedWrite();
        WatchedWrite(const WatchedWrite&) = delete;
        WatchedWrite& operator=(const WatchedWrite&) = delete;

    private:
        friend class StreamWatchdog;
        StreamWatchdog& watchdog_;
        grpc::ServerContext& call_;
        std::multimap<Clock::time_point, WatchedWrite*>::iterator entry_;
        bool watched_ = true;  // until it ends or is cut; under the watchdog's mutex
    };

private:
    void run();

    const std::chrono::milliseconds grace_;
    const size_t min_rate_;
    std::mutex mutex_;  // guards what follows
    std::condition_variable wake_;
    // The writes in progress, the first due first.
    std::multimap<Clock::time_point, WatchedWrite*> writes_;
    bool stopping_ = false;
    std::thread thread_;
};

}  // namespace aliquot
