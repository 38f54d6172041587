// A fixed number of places for requests that hold much memory or a thread for long (the
// HTTP API's image routes and event streams, gRPC's FetchImage and Watch), and a share of
// them that one peer address may hold: one that finds every place taken, or its address's
// share taken, is refused at once, never queued, and its caller answers 503 with
// Retry-After or RESOURCE_EXHAUSTED (docs/SECURITY.md, "HTTP image routes").
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace aliquot {

class Admission {
public:
    // `places` in all, at most `places_per_peer` of them (or `places`, if fewer) held by
    // one peer address, so that a client reconnecting as fast as it is cut leaves the
    // others some.
    Admission(size_t places, size_t places_per_peer);
    Admission(const Admission&) = delete;
    Admission& operator=(const Admission&) = delete;

    // A place, given back when the last copy goes: a response's content provider keeps
    // one until the response is sent, however it ends. The Admission must outlive every
    // place it gave.
    using Place = std::shared_ptr<void>;
    struct Ticket {
        Place place;  // null when refused
        // Refused because `peer` holds its share, while places were left for others.
        bool peer_share_full = false;
    };
    Ticket take(const std::string& peer);

    size_t places() const { return places_; }
    size_t places_per_peer() const { return places_per_peer_; }
    size_t taken() const;
    // Peer addresses holding a place now: the per-address account never holds more.
    size_t peers() const;

private:
    void give_back(const std::string& peer);

    const size_t places_, places_per_peer_;
    mutable std::mutex mutex_;
    size_t taken_ = 0;
    // Only peers holding a place: as many entries as places taken, at most.
    std::map<std::string, size_t> per_peer_;
};

}  // namespace aliquot
