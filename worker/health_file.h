// A worker's liveness as a file, for probes that can only look inside its container
// (Docker's HEALTHCHECK, a Kubernetes exec probe; a worker serves no port to ask). The
// file's modification time is kept at the moment every worker thread was last known not
// to be stuck (WorkerLoop::stalest_beat): a stuck thread stops it, and a probe fails once
// it is older than the probe allows (deploy/healthcheck.sh). The worker says when; the
// probe decides how old is too old.
#pragma once

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <mutex>
#include <thread>

namespace aliquot {

class HealthFile {
public:
    using AliveAt = std::function<std::chrono::steady_clock::time_point()>;

    // Creates `path` (throws std::runtime_error when it cannot), stamps it, and stamps it
    // again every `period` from a thread of its own.
    HealthFile(std::filesystem::path path, AliveAt alive_at,
               std::chrono::milliseconds period = std::chrono::seconds(1));
    // Stops, and removes the file: a worker that has ended is not alive.
    ~HealthFile();
    HealthFile(const HealthFile&) = delete;
    HealthFile& operator=(const HealthFile&) = delete;

    // Sets the file's modification time to alive_at() on the wall clock; whether it
    // could. A file removed meanwhile is made again.
    bool stamp();

private:
    std::filesystem::path path_;
    AliveAt alive_at_;
    std::chrono::milliseconds period_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;
    std::thread stamper_;
};

}  // namespace aliquot
