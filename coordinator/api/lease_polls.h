// How many Lease long-polls wait at once, per worker session and in all: each holds a
// server thread while it waits (up to 30 s), so without a bound a peer holding a worker
// token could make the coordinator start a thread per call (docs/SECURITY.md, "gRPC
// limits").
#pragma once

#include <map>
#include <mutex>
#include <string>

namespace aliquot {

class LeasePolls {
public:
    LeasePolls(int max_total, int max_per_session)
        : max_total_(max_total), max_per_session_(max_per_session) {}

    // A place to wait in, or none: held while the call waits, given back when it ends.
    class Place {
    public:
        Place(LeasePolls& polls, const std::string& session);
        ~Place();
        Place(const Place&) = delete;
        Place& operator=(const Place&) = delete;
        bool taken() const { return taken_; }

    private:
        LeasePolls& polls_;
        const std::string session_;
        bool taken_ = false;
    };

    int waiting();  // for tests

private:
    const int max_total_, max_per_session_;
    std::mutex mutex_;
    int total_ = 0;
    // Only sessions with a poll waiting: as many entries as places taken, at most.
    std::map<std::string, int> per_session_;
};

}  // namespace aliquot
