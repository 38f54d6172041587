#include "record_backlog.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <exception>

#include "bands.h"
#include "farm_log.h"

namespace aliquot {

namespace {

constexpr std::chrono::milliseconds kFirstDelay{500};
constexpr std::chrono::seconds kLongestDelay{30};
constexpr int kWriterNice = 10;

}  // namespace

void RecordBacklog::submit(std::string what, Write write, Clock::time_point now) {
    Pending p{std::move(what), std::move(write)};
    std::unique_lock lock(mutex_);
    if (background_) {
        queue_.push_back(std::move(p));
        wake_.notify_all();
        return;
    }
    if (queue_.empty()) {
        // Without a writer the caller serialises submits and retries (the coordinator's
        // lock): running the write unlocked here cannot interleave with another.
        lock.unlock();
        std::string error;
        const bool ok = run(p, error);
        lock.lock();
        note(p, ok, error, now);
        if (ok) return;
    }
    queue_.push_back(std::move(p));
}

void RecordBacklog::retry(Clock::time_point now) {
    std::unique_lock lock(mutex_);
    if (background_ || queue_.empty() || now < next_try_) return;
    while (!queue_.empty()) {
        Pending& p = queue_.front();  // deque: references survive push_back
        lock.unlock();
        std::string error;
        const bool ok = run(p, error);
        lock.lock();
        note(p, ok, error, now);
        if (!ok) return;
        queue_.pop_front();
    }
}

bool RecordBacklog::run(Pending& p, std::string& error) {
    try {
        p.write();
        return true;
    } catch (const std::exception& e) {
        error = e.what();
    } catch (...) {
        error = "unknown error";
    }
    return false;
}

void RecordBacklog::note(const Pending& p, bool ok, const std::string& error,
                         Clock::time_point now) {
    if (!ok) {
        ++failures_;
        const bool first = warning_.empty();
        warning_ = "cannot " + p.what + ": " + error;
        // Logged when writes start failing and then at most every 30 s, not every retry.
        if (first || delay_ >= kLongestDelay)
            log_farm_error(warning_ + " (kept, retrying)", "record_write_failing");
        delay_ = first ? Clock::duration(kFirstDelay)
                       : std::min<Clock::duration>(2 * delay_, kLongestDelay);
        next_try_ = now + delay_;
        return;
    }
    if (!warning_.empty() && queue_.size() <= 1)
        log_farm_error("the run record is written again", "record_written_again");
    if (queue_.size() <= 1) {
        warning_.clear();
        delay_ = {};
    }
}

void RecordBacklog::start_writer() {
    std::lock_guard lock(mutex_);
    if (background_) return;
    background_ = true;
    stopping_ = false;
    writer_ = std::thread([this] { writer_main(); });
}

void RecordBacklog::stop_writer() {
    {
        std::lock_guard lock(mutex_);
        if (!background_) return;
        stopping_ = true;
    }
    wake_.notify_all();
    if (writer_.joinable()) writer_.join();
    std::lock_guard lock(mutex_);
    background_ = false;
    idle_.notify_all();
}

void RecordBacklog::writer_main() {
    // Records and checkpoints are background work: on the coordinator's cores they gave
    // way neither to a round end's passes, which then ran on one core of two (a 1920x1080
    // checkpoint write is ~0.1 s of CPU), nor to workers on the same machine. Nice 10
    // weighs a tenth of a normal thread where the CPU is contended and nothing where it
    // is not, so the writes still go on under full load. (Linux: a thread's own nice.)
    setpriority(PRIO_PROCESS, id_t(gettid()), kWriterNice);
    keep_passes_on_this_thread();  // threads it started would inherit its nice
    std::unique_lock lock(mutex_);
    while (true) {
        if (queue_.empty()) {
            idle_.notify_all();
            if (stopping_) return;
            wake_.wait(lock);
            continue;
        }
        if (!stopping_ && Clock::now() < next_try_) {
            wake_.wait_until(lock, next_try_);
            continue;
        }
        Pending& p = queue_.front();  // deque: references survive push_back
        running_ = true;
        lock.unlock();
        std::string error;
        const bool ok = run(p, error);
        lock.lock();
        running_ = false;
        note(p, ok, error, Clock::now());
        if (ok) {
            queue_.pop_front();
        } else if (stopping_) {
            // Stopping on a failing disk: what is left is redone after a restart.
            queue_.clear();
            idle_.notify_all();
            return;
        }
    }
}

bool RecordBacklog::wait_idle(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return idle_.wait_for(lock, timeout, [this] { return queue_.empty() && !running_; });
}

size_t RecordBacklog::waiting() const {
    std::lock_guard lock(mutex_);
    return queue_.size();
}

std::string RecordBacklog::warning() const {
    std::lock_guard lock(mutex_);
    return warning_;
}

uint64_t RecordBacklog::failures() const {
    std::lock_guard lock(mutex_);
    return failures_;
}

}  // namespace aliquot
