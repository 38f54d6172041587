// WorkerRegistry: the workers a coordinator has heard from and their links. A worker
// (a name) registers as often as it likes; each registration is a link, the token every
// later call of that worker carries (WorkerLink's "session" parameter; in the farm
// "session" is a render's). It keeps the workers' counts and rows, marks the silent ones
// lost, forgets those silent for long, and bounds both maps (CoordinatorOptions).
//
// Its own lock: every public method takes it. While it is held the registry may ask the
// LeaseTable which links hold leases (`leases_by_link`), write the archive's queue and
// log events; never the other way round (docs/FARM.md, "Locks").
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "render_archive.h"
#include "render_events.h"
#include "render_info.h"

namespace aliquot {

// Thrown by register_link when every one of max_links links, or of max_workers workers,
// holds a lease.
class TooManyWorkers : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// The host a network peer called from, without its port ("ipv4:10.0.0.5:41234" ->
// "ipv4:10.0.0.5"): whom failures count against.
std::string host_of_peer(const std::string& peer);

// The most threads a worker may state at Register (the api refuses more): what it states
// counts as the farm's cores, for which rounds are cut. The largest machines have a few
// hundred. It is also the most cores one address counts for (alive_cores).
inline constexpr uint32_t kMaxWorkerThreads = 1024;

// How long a worker's merged jobs count toward its cores (WorkerLimits::working_within)
// for a farm whose leases last `lease_time`: at least 10 minutes, whatever the lease
// time. An honest worker idles between rounds for as long as a round's end takes (17-25 s
// of denoising at 1080p), between renders, or behind a straggler: a window of one lease
// time (5 s with --lease-seconds 5) dropped it to no core then, and the next round was
// cut for almost no one (16 jobs), the round after only for the workers that took those.
std::chrono::milliseconds working_window(std::chrono::milliseconds lease_time);

struct WorkerLimits {
    std::chrono::milliseconds lost_after{10000};
    std::chrono::milliseconds forget_after{std::chrono::hours(1)};
    size_t max_links = 4096;
    size_t max_workers = 4096;
    // Workers (names) and links from one address (host_of_peer) at once: past either, a
    // Register from it drops its own longest-silent entry that holds no lease and is
    // lost, or is refused (TooManyWorkers), so that one address alone cannot fill the
    // registry. Four addresses at their share can (4 x 1024 = max_workers), and so can
    // one IPv6 holder with many addresses; past max_workers a new name drops the
    // longest-silent name holding no lease, from whichever address
    // (make_room_for_a_worker).
    size_t max_workers_per_host = 1024;
    // A worker's merged jobs count toward its cores for between one and two of these
    // (counted in windows this long): see alive_cores and working_window.
    std::chrono::milliseconds working_within{std::chrono::minutes(10)};
};

class WorkerRegistry {
public:
    // One registration of a worker.
    struct Link {
        std::string worker;    // its name
        std::string identity;  // whom its failures count against (FailurePolicy)
        bool trusted = false;  // in this process (register_worker without a peer)
        int64_t last_seen_ms = 0;
    };

    // The links holding a lease now (never dropped to make room or for silence), each
    // with how many of its leases are granted (LeaseTable::leases_by_link).
    using LeasesByLink = std::unordered_map<std::string, size_t>;
    WorkerRegistry(WorkerLimits limits, RenderArchive& archive, RenderEvents& events,
                   std::function<LeasesByLink()> leases_by_link);

    // A new link for `name`, its worker touched and its row written; throws
    // TooManyWorkers when no room can be made.
    std::string register_link(const std::string& name, uint32_t threads,
                              std::string identity, bool trusted);
    // The link `link`, its worker touched (heard from now); throws WorkerUnknown for a
    // link this registry did not issue. A copy: the entry may go as soon as the lock is
    // let go.
    Link link_of(const std::string& link);
    // A lease poll of `link` began or ended. A worker in a poll is talking to us however
    // long the poll waits, so tick() marks no worker with a poll in progress lost, and
    // the poll's end counts as heard from (docs/FARM.md, "Workers lost").
    void poll_began(const std::string& link);
    void poll_ended(const std::string& link);
    // poll_began and poll_ended around a lease poll.
    class Poll {
    public:
        Poll(WorkerRegistry& registry, const std::string& link);
        ~Poll();
        Poll(const Poll&) = delete;
        Poll& operator=(const Poll&) = delete;

    private:
        WorkerRegistry& registry_;
        const std::string& link_;
    };
    // What a worker says of itself; false for an unknown name.
    bool describe(const std::string& name, std::string host, std::string version);
    bool knows(const std::string& name) const;
    size_t links() const;

    void note_merged(const std::string& name, uint64_t samples, double wall_seconds);
    void note_failure(const std::string& name);

    // The identities of the links of workers registered and not lost: those a job may go
    // to (RenderSession::issue). Rebuilt only when workers register, are lost, come back
    // or are forgotten; an immutable snapshot, so a call can use it under its render's
    // lock alone.
    std::shared_ptr<const std::set<std::string>> alive_identities();
    // The farm's live worker cores, for which rounds are cut (two jobs each,
    // round_cutter.h): each alive worker counts as many of its stated threads as it has
    // shown work for, the granted leases its links hold now plus the jobs it merged in
    // the working window (working_within; the threads of workers in this process count
    // always), and one address at most kMaxWorkerThreads. A name costs a holder of the
    // worker token nothing and a heartbeat keeps it alive, so threads that idle names
    // state counted as cores had one holder (4096 names x 1024 threads) cut every round
    // of every render into the smallest tiles; and a name's whole statement counted for
    // one lease renewed forever or one cheap merge a window. Counting jobs ties the count
    // to jobs actually taken (an honest worker holds about a lease a thread while it
    // traces, and merges more), and the cap per address makes many names on one machine
    // (or behind one NAT) one machine. Rebuilt (O(workers + leases)) at every tick, and
    // at the next read after workers are lost, forgotten, new, or register with other
    // threads, address or trust, and after a merge of a worker not counting all its
    // threads.
    size_t alive_cores();

    // Writes the workers' counts, marks the silent lost, forgets those silent for long
    // (and, when `sweep_rows`, the store's rows silent as long); whether any was lost.
    bool tick(int64_t now_ms, bool sweep_rows);

    // Every worker, each with the labels ("render/job") of the leases its links hold
    // (`labels_by_link`, LeaseTable::labels_by_link).
    std::vector<WorkerStatus> statuses(
        const std::map<std::string, std::vector<std::string>>& labels_by_link) const;

private:
    struct WorkerEntry {
        uint32_t threads = 0;
        int64_t last_seen_ms = 0;
        uint64_t samples = 0;
        uint64_t unrecorded = 0;  // merged samples not yet added to the store (see tick)
        double rate = 0;          // samples/s, smoothed over recent jobs
        bool lost = false;
        std::string host, version;  // describe: for the workers list only
        std::string address;        // the identity its last registration came from
        bool trusted = false;       // that registration was in this process
        // Jobs it merged in the working window `merge_window` (now / working_within) and
        // in the one before it, at most kMaxWorkerThreads each (merges_counted).
        int64_t merge_window = -2;
        uint32_t merged_in_window = 0, merged_window_before = 0;
        uint32_t counted = 0;   // its cores in alive_cores_ (count_cores)
        uint32_t failures = 0;  // jobs it reported failed
        uint32_t polling = 0;   // lease polls in progress (poll_began)
        // last_seen_ms as the store last has it: refreshed now and then (tick), so that
        // a row silent for forget_after is a worker gone, not an idle one.
        int64_t stored_seen_ms = 0;
    };

    WorkerEntry& touch_worker(const std::string& name);
    void set_alive(const std::string& name, bool alive);
    // Drops `name` and its links from memory, and its row from the store.
    void forget_worker(const std::string& name);
    // Make room for one more worker (a name not yet known) or link, or throw
    // TooManyWorkers.
    void make_room_for_a_worker(const std::string& name);
    void make_room_for_a_link();
    // The same within `address`'s share (max_workers_per_host), dropping only its own
    // lost entries: throws TooManyWorkers when it has no room.
    void make_room_on_host(const std::string& name, const std::string& address);
    // Drops links silent for forget_after that hold no lease, and workers lost that long
    // with no link left.
    void forget_silent_workers(int64_t now_ms);
    void refresh_alive();
    // The workers (names) with a link holding a lease now, each with its granted leases.
    std::unordered_map<std::string, size_t> names_holding_leases() const;
    // The jobs `w` merged that count toward its cores at `now_ms`: those of this working
    // window and of the one before.
    uint32_t merges_counted(const WorkerEntry& w, int64_t now_ms) const;
    // Rebuilds alive_cores_ as of `now_ms`.
    void count_cores(int64_t now_ms);

    mutable std::mutex mutex_;
    WorkerLimits limits_;
    RenderArchive& archive_;
    RenderEvents& events_;
    std::function<LeasesByLink()> leases_by_link_;
    std::unordered_map<std::string, Link> links_;  // by link token
    std::map<std::string, WorkerEntry> workers_;   // by name
    std::set<std::string> alive_;  // names in workers_ that registered and are not lost
    std::shared_ptr<const std::set<std::string>> alive_snapshot_ =
        std::make_shared<const std::set<std::string>>();
    bool alive_dirty_ = false;
    bool cores_dirty_ = false;  // alive_cores_ is rebuilt at its next read
    size_t alive_cores_ = 0;
};

}  // namespace aliquot
