#include "courier.h"

#include <utility>

namespace aliquot {

Courier::Courier() : thread_([this](std::stop_token stop) { run(stop); }) {}

Courier::~Courier() {
    wait();  // then the jthread's own destructor stops run() and joins it
}

void Courier::send(Call call) {
    {
        std::lock_guard lock(mutex_);
        call_ = std::move(call);
        busy_ = true;
        answered_ = false;
        answer_.reset();
    }
    changed_.notify_all();
}

bool Courier::busy() const {
    std::lock_guard lock(mutex_);
    return busy_;
}

std::optional<LeaseGrant> Courier::wait() {
    std::unique_lock lock(mutex_);
    if (!busy_) return std::nullopt;
    changed_.wait(lock, [&] { return answered_; });
    busy_ = false;
    return std::exchange(answer_, std::nullopt);
}

void Courier::run(std::stop_token stop) {
    std::unique_lock lock(mutex_);
    while (true) {
        if (!changed_.wait(lock, stop, [&] { return bool(call_); })) return;
        Call call = std::exchange(call_, nullptr);
        lock.unlock();
        std::optional<LeaseGrant> answer;
        try {
            answer = call();
        } catch (...) {
            // The calls handle what the coordinator says themselves; whatever still
            // escapes is a lease not had, and the tracing thread asks again.
        }
        lock.lock();
        answer_ = std::move(answer);
        answered_ = true;
        changed_.notify_all();
    }
}

}  // namespace aliquot
