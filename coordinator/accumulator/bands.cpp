#include "bands.h"

#include <time.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace aliquot {

namespace {

uint64_t thread_cpu_nanoseconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return uint64_t(t.tv_sec) * 1000000000u + uint64_t(t.tv_nsec);
}

// One pass being run: its bands are handed out by an atomic counter to whichever
// thread asks next. Which thread runs a band never changes what the band computes.
struct Pass {
    size_t items = 0, band = 0, bands = 0;
    const std::function<void(size_t, size_t, size_t)>* fn = nullptr;
    std::atomic<size_t> next{0};
    std::atomic<size_t> done{0};
    std::mutex error_mutex;
    std::exception_ptr error;

    // Runs bands until none is left.
    void run() {
        size_t finished = 0;
        for (size_t b; (b = next.fetch_add(1)) < bands;) {
            try {
                (*fn)(b, b * band, std::min(items, (b + 1) * band));
            } catch (...) {
                std::lock_guard lock(error_mutex);
                if (!error) error = std::current_exception();
            }
            ++finished;
        }
        if (finished) done.fetch_add(finished);
    }
};

// Set on a thread while it runs a pass's bands: a pass started inside one runs inline
// (a std::mutex must not be try-locked by its owner).
thread_local bool in_pass = false;

class BandPool {
public:
    ~BandPool() {
        {
            std::lock_guard lock(mutex_);
            quit_ = true;
        }
        wake_.notify_all();
        for (std::thread& t : threads_) t.join();
    }

    void run(size_t items, size_t band,
             const std::function<void(size_t, size_t, size_t)>& fn) {
        Pass pass;
        pass.items = items;
        pass.band = band;
        pass.bands = band_count(items, band);
        pass.fn = &fn;
        if (pass.bands == 0) return;
        std::unique_lock<std::mutex> busy;
        if (!in_pass) busy = std::unique_lock(busy_, std::try_to_lock);
        const bool outer = in_pass;
        in_pass = true;
        if (!busy || pass.bands == 1 || threads_wanted_ <= 1) {
            pass.run();  // on this thread alone: same bands, same results
        } else {
            start_threads();
            {
                std::lock_guard lock(mutex_);
                pass_ = &pass;
                ++generation_;
            }
            wake_.notify_all();
            pass.run();
            std::unique_lock lock(mutex_);
            finished_.wait(
                lock, [&] { return pass.done.load() == pass.bands && inside_ == 0; });
            pass_ = nullptr;
        }
        in_pass = outer;
        if (pass.error) std::rethrow_exception(pass.error);
    }

    unsigned threads() const { return threads_wanted_; }
    void set_threads(unsigned n) {
        std::lock_guard busy(busy_);  // not while a pass runs
        threads_wanted_ = std::max(1u, n);
    }
    double cpu_seconds() const { return 1e-9 * double(cpu_ns_.load()); }

private:
    void start_threads() {
        std::lock_guard lock(mutex_);
        while (threads_.size() + 1 < threads_wanted_)
            threads_.emplace_back([this, index = threads_.size()] { work(index); });
    }

    void work(size_t index) {
        uint64_t seen = 0;
        std::unique_lock lock(mutex_);
        while (true) {
            wake_.wait(lock, [&] { return quit_ || (pass_ && generation_ != seen); });
            if (quit_) return;
            seen = generation_;
            // Threads beyond the count wanted now (it was lowered) sit this pass out.
            if (index + 1 >= threads_wanted_) continue;
            Pass* pass = pass_;
            ++inside_;
            lock.unlock();
            const uint64_t began = thread_cpu_nanoseconds();
            in_pass = true;
            pass->run();
            in_pass = false;
            cpu_ns_ += thread_cpu_nanoseconds() - began;
            lock.lock();
            --inside_;
            finished_.notify_all();
        }
    }

    std::mutex busy_;  // held by the caller whose pass the pool runs
    std::mutex mutex_;
    std::condition_variable wake_, finished_;
    std::vector<std::thread> threads_;
    Pass* pass_ = nullptr;
    uint64_t generation_ = 0;
    int inside_ = 0;  // pool threads inside the current pass
    bool quit_ = false;
    std::atomic<unsigned> threads_wanted_{
        std::max(1u, std::thread::hardware_concurrency())};
    std::atomic<uint64_t> cpu_ns_{0};
};

BandPool& pool() {
    static BandPool instance;
    return instance;
}

}  // namespace

void for_each_band(size_t items, size_t band,
                   const std::function<void(size_t, size_t, size_t)>& fn) {
    pool().run(items, band, fn);
}

void keep_passes_on_this_thread() { in_pass = true; }  // never reset on this thread

unsigned band_threads() { return pool().threads(); }

void set_band_threads(unsigned threads) { pool().set_threads(threads); }

double band_pool_cpu_seconds() { return pool().cpu_seconds(); }

}  // namespace aliquot
