// Courier: one tracing thread's calls to the coordinator, made on a thread of their own,
// so that the thread traces its next job while the last one's sums travel and merge
// (docs/FARM.md, "A job in flight while the next is traced").
#pragma once

#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

#include "lease.h"

namespace aliquot {

class Courier {
public:
    // A call to the coordinator that may answer with a lease.
    using Call = std::function<std::optional<LeaseGrant>()>;

    Courier();
    // Waits for the call in flight, if any: its lease, untraced, is the caller's to give
    // back before this (wait() then hand it back).
    ~Courier();
    Courier(const Courier&) = delete;
    Courier& operator=(const Courier&) = delete;

    // Starts `call` on the courier's thread. One call at a time: only when !busy().
    void send(Call call);
    // A call was sent and its answer not yet taken.
    bool busy() const;
    // The answer of the call sent, once it has come (nullopt when none was sent, or the
    // call threw). The caller does not beat meanwhile: a call stuck on the courier's
    // thread shows in the worker's liveness as it did when the caller made it itself.
    std::optional<LeaseGrant> wait();

private:
    void run(std::stop_token stop);

    mutable std::mutex mutex_;
    std::condition_variable_any changed_;
    Call call_;          // set by send, taken by the courier's thread
    bool busy_ = false;  // from send until wait takes the answer
    bool answered_ = false;
    std::optional<LeaseGrant> answer_;
    std::jthread thread_;  // last: started once the members above exist
};

}  // namespace aliquot
