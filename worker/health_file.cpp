#include "health_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace aliquot {

namespace {

bool create(const std::filesystem::path& path) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) return false;
    ::close(fd);
    return true;
}

}  // namespace

HealthFile::HealthFile(std::filesystem::path path, AliveAt alive_at,
                       std::chrono::milliseconds period)
    : path_(std::move(path)), alive_at_(std::move(alive_at)), period_(period) {
    if (!create(path_))
        throw std::runtime_error("--health-file: cannot create " + path_.string() + ": " +
                                 std::strerror(errno));
    stamp();
    stamper_ = std::thread([this] {
        std::unique_lock lock(mutex_);
        while (!wake_.wait_for(lock, period_, [this] { return stopping_; })) {
            lock.unlock();
            stamp();  // a failure is tried again next period; the probe sees the age
            lock.lock();
        }
    });
}

HealthFile::~HealthFile() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    wake_.notify_all();
    stamper_.join();
    std::error_code ec;
    std::filesystem::remove(path_, ec);
}

bool HealthFile::stamp() {
    using namespace std::chrono;
    // The steady clock's moment on the wall clock, which is what file times are.
    const auto age = steady_clock::now() - alive_at_();
    const auto wall = duration_cast<nanoseconds>(
        (system_clock::now() - duration_cast<system_clock::duration>(age))
            .time_since_epoch());
    timespec times[2];
    times[0].tv_sec = 0;
    times[0].tv_nsec = UTIME_OMIT;  // access time: untouched
    times[1].tv_sec = time_t(wall.count() / 1000000000);
    times[1].tv_nsec = long(wall.count() % 1000000000);
    if (::utimensat(AT_FDCWD, path_.c_str(), times, 0) == 0) return true;
    return errno == ENOENT && create(path_) &&
           ::utimensat(AT_FDCWD, path_.c_str(), times, 0) == 0;
}

}  // namespace aliquot
