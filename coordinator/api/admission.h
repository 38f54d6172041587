// A fixed number of places for requests that hold much memory or a thread for long (the
// HTTP API's image routes, its event streams): one that finds every place taken is
// refused at once, never queued, and its caller answers 503 with Retry-After
// (docs/SECURITY.md, "HTTP image routes").
#pragma once

#include <cstddef>
#include <memory>
#include <mutex>

namespace aliquot {

class Admission {
public:
    explicit Admission(size_t places) : places_(places) {}
    Admission(const Admission&) = delete;
    Admission& operator=(const Admission&) = delete;

    // A place, given back when the last copy goes: a response's content provider keeps
    // one until the response is sent, however it ends. Null when every place is taken.
    // The Admission must outlive every place it gave.
    using Place = std::shared_ptr<void>;
    Place take();

    size_t places() const { return places_; }
    size_t taken() const;

private:
    const size_t places_;
    mutable std::mutex mutex_;
    size_t taken_ = 0;
};

}  // namespace aliquot
