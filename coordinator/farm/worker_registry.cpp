#include "worker_registry.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "farm_log.h"
#include "secret.h"
#include "unix_millis.h"

namespace aliquot {

// The port is the caller's to choose with each connection; the host is not.
std::string host_of_peer(const std::string& peer) {
    if (peer.empty()) return "unknown peer";
    const bool ip = peer.rfind("ipv4:", 0) == 0 || peer.rfind("ipv6:", 0) == 0;
    const size_t colon = peer.rfind(':');
    if (!ip || colon <= 5 || colon + 1 == peer.size()) return peer;
    for (size_t i = colon + 1; i < peer.size(); ++i)
        if (!std::isdigit(static_cast<unsigned char>(peer[i]))) return peer;
    return peer.substr(0, colon);
}

std::chrono::milliseconds working_window(std::chrono::milliseconds lease_time) {
    return std::max<std::chrono::milliseconds>(lease_time, std::chrono::minutes(10));
}

WorkerRegistry::WorkerRegistry(WorkerLimits limits, RenderArchive& archive,
                               RenderEvents& events,
                               std::function<LeasesByLink()> leases_by_link)
    : limits_(limits),
      archive_(archive),
      events_(events),
      leases_by_link_(std::move(leases_by_link)) {
    // Merges are counted in windows of working_within (note_merged): never of 0 ms.
    limits_.working_within =
        std::max(limits_.working_within, std::chrono::milliseconds(1));
}

WorkerRegistry::WorkerEntry& WorkerRegistry::touch_worker(const std::string& name) {
    const auto [it, is_new] = workers_.try_emplace(name);
    WorkerEntry& w = it->second;
    const int64_t now = unix_millis_now();
    w.last_seen_ms = now;
    // A worker first heard of here gets its row now, so that marking it lost later has
    // a row to mark. (Since worker links, only register_link meets a new name.)
    if (is_new || w.lost) {
        archive_.record_worker(name, w.threads, now);
        w.stored_seen_ms = now;
    }
    w.lost = false;
    set_alive(name, true);
    return w;
}

void WorkerRegistry::set_alive(const std::string& name, bool alive) {
    const bool changed_set = alive ? alive_.insert(name).second : alive_.erase(name) > 0;
    if (changed_set) alive_dirty_ = cores_dirty_ = true;
}

void WorkerRegistry::refresh_alive() {
    if (!alive_dirty_) return;
    std::set<std::string> hosts;
    for (const auto& [link, entry] : links_)
        if (alive_.count(entry.worker)) hosts.insert(entry.identity);
    alive_snapshot_ = std::make_shared<const std::set<std::string>>(hosts);
    alive_dirty_ = false;
}

std::unordered_map<std::string, size_t> WorkerRegistry::names_holding_leases() const {
    std::unordered_map<std::string, size_t> names;
    for (const auto& [link, granted] : leases_by_link_())
        if (const auto it = links_.find(link); it != links_.end())
            names[it->second.worker] += granted;
    return names;
}

uint32_t WorkerRegistry::merges_counted(const WorkerEntry& w, int64_t now_ms) const {
    const int64_t window = now_ms / limits_.working_within.count();
    if (w.merge_window == window) return w.merged_in_window + w.merged_window_before;
    return w.merge_window + 1 == window ? w.merged_in_window : 0;
}

void WorkerRegistry::count_cores(int64_t now_ms) {
    const std::unordered_map<std::string, size_t> leases = names_holding_leases();
    // An honest worker holds about a lease a thread while it traces (and one leased ahead
    // each), and merges at least a job a thread a round, so it counts all its threads
    // through a round and for the working window after, idle between rounds or renders.
    std::unordered_map<std::string, size_t> by_address;
    for (auto& [name, w] : workers_) {
        size_t shown = 0;
        if (alive_.count(name)) {
            const auto held = leases.find(name);
            shown = w.trusted ? w.threads
                              : std::min<size_t>(
                                    w.threads, (held == leases.end() ? 0 : held->second) +
                                                   merges_counted(w, now_ms));
        }
        w.counted = uint32_t(shown);
        if (shown > 0) by_address[w.address] += shown;
    }
    // Several workers on one machine share its cores, and one machine states at most
    // kMaxWorkerThreads; a farm behind one NAT address past it has its rounds cut for
    // that many (2048 jobs and more a round: most of an image's smallest tiles anyway).
    alive_cores_ = 0;
    for (const auto& [address, threads] : by_address)
        alive_cores_ += std::min<size_t>(threads, kMaxWorkerThreads);
    cores_dirty_ = false;
}

std::shared_ptr<const std::set<std::string>> WorkerRegistry::alive_identities() {
    std::lock_guard lock(mutex_);
    refresh_alive();
    return alive_snapshot_;
}

size_t WorkerRegistry::alive_cores() {
    std::lock_guard lock(mutex_);
    if (cores_dirty_) count_cores(unix_millis_now());
    return alive_cores_;
}

WorkerRegistry::Link WorkerRegistry::link_of(const std::string& link) {
    std::lock_guard lock(mutex_);
    const auto it = links_.find(link);
    if (it == links_.end()) throw WorkerUnknown("unknown worker session: register again");
    it->second.last_seen_ms = unix_millis_now();
    touch_worker(it->second.worker);
    return it->second;
}

void WorkerRegistry::poll_began(const std::string& link) {
    std::lock_guard lock(mutex_);
    if (const auto it = links_.find(link); it != links_.end())
        if (const auto w = workers_.find(it->second.worker); w != workers_.end())
            ++w->second.polling;
}

void WorkerRegistry::poll_ended(const std::string& link) {
    std::lock_guard lock(mutex_);
    // The link or its worker may have been dropped meanwhile (to make room): then there
    // is no one to touch, and its next call is told to register again.
    const auto it = links_.find(link);
    if (it == links_.end() || !workers_.count(it->second.worker)) return;
    it->second.last_seen_ms = unix_millis_now();
    WorkerEntry& w = touch_worker(it->second.worker);
    if (w.polling > 0) --w.polling;
}

WorkerRegistry::Poll::Poll(WorkerRegistry& registry, const std::string& link)
    : registry_(registry), link_(link) {
    registry_.poll_began(link_);
}

WorkerRegistry::Poll::~Poll() {
    try {
        registry_.poll_ended(link_);
    } catch (const std::exception& e) {  // a full disk writing its row
        log_farm_error(std::string("lease poll: ") + e.what());
    }
}

bool WorkerRegistry::knows(const std::string& name) const {
    std::lock_guard lock(mutex_);
    return workers_.count(name) > 0;
}

size_t WorkerRegistry::links() const {
    std::lock_guard lock(mutex_);
    return links_.size();
}

namespace {

// The entry of `entries` heard from longest ago whose key is not in `holding`, or end().
template <class Entries, class Holding>
typename Entries::iterator longest_silent(Entries& entries, const Holding& holding) {
    auto oldest = entries.end();
    for (auto it = entries.begin(); it != entries.end(); ++it)
        if (!holding.count(it->first) &&
            (oldest == entries.end() ||
             it->second.last_seen_ms < oldest->second.last_seen_ms))
            oldest = it;
    return oldest;
}

}  // namespace

void WorkerRegistry::make_room_for_a_link() {
    if (links_.size() < limits_.max_links) return;
    const auto oldest = longest_silent(links_, leases_by_link_());
    if (oldest == links_.end())
        throw TooManyWorkers("the coordinator has " + std::to_string(links_.size()) +
                             " worker sessions, each holding a lease; try again later");
    // Its worker, if it is still there, is told to register again at its next call.
    links_.erase(oldest);
    alive_dirty_ = true;
}

void WorkerRegistry::forget_worker(const std::string& name) {
    std::erase_if(links_, [&name](const auto& kv) { return kv.second.worker == name; });
    set_alive(name, false);
    alive_dirty_ = cores_dirty_ = true;
    workers_.erase(name);
    archive_.forget_worker(name);
}

void WorkerRegistry::make_room_for_a_worker(const std::string& name) {
    if (workers_.size() < limits_.max_workers || workers_.count(name)) return;
    const auto holding = names_holding_leases();
    const auto oldest = longest_silent(workers_, holding);
    if (oldest == workers_.end())
        throw TooManyWorkers("the coordinator knows " + std::to_string(workers_.size()) +
                             " workers, each holding a lease; try again later");
    // Its samples not yet recorded go with it; if it is still there, it is told to
    // register again at its next call.
    forget_worker(std::string(oldest->first));
}

void WorkerRegistry::make_room_on_host(const std::string& name,
                                       const std::string& address) {
    const size_t most = limits_.max_workers_per_host;
    // Fewer in all than an address's share: no address is at it (no scan below).
    if (workers_.size() < most && links_.size() < most) return;
    const int64_t now = unix_millis_now(), lost_after = limits_.lost_after.count();
    // Only entries of `address` that are lost (silent past lost_after, in no lease poll)
    // and hold no lease make room, and links of the name registering again: a host whose
    // workers restart under new names gets in, and one that has `most` workers at once is
    // told so, where dropping a live one would have it register again and drop another,
    // without end.
    const auto is_lost = [&](const std::string& worker, int64_t last_seen_ms) {
        const auto w = workers_.find(worker);
        return now - last_seen_ms > lost_after &&
               (w == workers_.end() || w->second.polling == 0);
    };
    const auto refuse = [&](size_t count, const std::string& what) {
        return TooManyWorkers(
            address + " has " + std::to_string(count) + " " + what +
            ", the most one address may (--max-workers-per-host), none of "
            "them lost; try again later");
    };
    // Its names first (a lost one dropped takes its links with it), then its links.
    size_t names_here = 0;  // 0 for a name this address registered before
    if (const auto it = workers_.find(name);
        it == workers_.end() || it->second.address != address)
        for (const auto& [worker, w] : workers_) names_here += w.address == address;
    if (names_here >= most) {
        const auto holding = names_holding_leases();
        auto oldest = workers_.end();
        for (auto it = workers_.begin(); it != workers_.end(); ++it)
            if (it->second.address == address && !holding.count(it->first) &&
                is_lost(it->first, it->second.last_seen_ms) &&
                (oldest == workers_.end() ||
                 it->second.last_seen_ms < oldest->second.last_seen_ms))
                oldest = it;
        if (oldest == workers_.end()) throw refuse(names_here, "workers registered");
        forget_worker(std::string(oldest->first));
    }
    size_t links_here = 0;
    for (const auto& [token, link] : links_) links_here += link.identity == address;
    if (links_here < most) return;
    const LeasesByLink holding = leases_by_link_();
    auto oldest = links_.end();
    for (auto it = links_.begin(); it != links_.end(); ++it)
        if (it->second.identity == address && !holding.count(it->first) &&
            (it->second.worker == name ||
             is_lost(it->second.worker, it->second.last_seen_ms)) &&
            (oldest == links_.end() ||
             it->second.last_seen_ms < oldest->second.last_seen_ms))
            oldest = it;
    if (oldest == links_.end()) throw refuse(links_here, "worker sessions");
    links_.erase(oldest);
    alive_dirty_ = true;
}

void WorkerRegistry::forget_silent_workers(int64_t now_ms) {
    const int64_t after = limits_.forget_after.count();
    const LeasesByLink holding = leases_by_link_();
    std::set<std::string> named;
    for (auto it = links_.begin(); it != links_.end();) {
        if (now_ms - it->second.last_seen_ms > after && !holding.count(it->first)) {
            it = links_.erase(it);
            alive_dirty_ = true;
        } else {
            named.insert(it->second.worker);
            ++it;
        }
    }
    std::vector<std::string> gone;
    for (const auto& [name, w] : workers_)
        if (w.lost && w.unrecorded == 0 && now_ms - w.last_seen_ms > after &&
            !named.count(name))
            gone.push_back(name);  // a lost worker is not in alive_
    for (const std::string& name : gone) forget_worker(name);
}

bool WorkerRegistry::describe(const std::string& name, std::string host,
                              std::string version) {
    std::lock_guard lock(mutex_);
    const auto it = workers_.find(name);
    if (it == workers_.end()) return false;
    it->second.host = std::move(host);
    it->second.version = std::move(version);
    return true;
}

std::string WorkerRegistry::register_link(const std::string& name, uint32_t threads,
                                          std::string identity, bool trusted) {
    std::lock_guard lock(mutex_);
    // First: a refused registration adds nothing (the silent link or worker one of
    // these dropped before the other refused stays dropped). The address's own share
    // before the whole registry's, so that a full share drops none of another's.
    if (!trusted) make_room_on_host(name, identity);
    make_room_for_a_link();
    make_room_for_a_worker(name);
    const bool is_new = !workers_.count(name);
    WorkerEntry& w = touch_worker(name);
    // A Register flood of a known name changes no count: a recount (it allocates) on
    // every Lease and Complete after each would be its cost to the farm.
    if (is_new || w.threads != threads || w.address != identity || w.trusted != trusted)
        cores_dirty_ = true;
    w.threads = threads;
    w.address = identity;
    w.trusted = trusted;
    set_alive(name, true);
    // A full disk must not keep workers out: the row is written again when it returns.
    archive_.record_worker(name, threads, w.last_seen_ms);
    w.stored_seen_ms = w.last_seen_ms;
    // A new link each time; earlier ones of the same name stay valid (their leases are
    // still theirs), so registering with a worker's name neither takes its leases nor
    // locks it out.
    events_.on_worker(
        EventKind::WorkerRegistered, name,
        {log_number("threads", int64_t(threads)), log_text("host", identity)});
    std::string link;
    do link = random_hex(16);
    while (links_.count(link));
    // The alive identities change only with a new one (the worker is alive now; one
    // that just came back has marked them already): a Register flood as before rebuilds
    // (allocates) nothing on the Leases and Completes after it.
    if (!alive_snapshot_->count(identity)) alive_dirty_ = true;
    links_.emplace(link, Link{name, std::move(identity), trusted, unix_millis_now()});
    return link;
}

void WorkerRegistry::note_merged(const std::string& name, uint64_t samples,
                                 double wall_seconds) {
    std::lock_guard lock(mutex_);
    // The worker may have been forgotten meanwhile (it was silent for long): its counts
    // go with it.
    const auto it = workers_.find(name);
    if (it == workers_.end()) return;
    WorkerEntry& w = it->second;
    w.samples += samples;
    // It has shown it works: another of its threads counts from the next round cut
    // (alive_cores), up to all it states.
    const int64_t window = unix_millis_now() / limits_.working_within.count();
    if (window != w.merge_window) {
        w.merged_window_before = w.merge_window + 1 == window ? w.merged_in_window : 0;
        w.merged_in_window = 0;
        w.merge_window = window;
    }
    w.merged_in_window = std::min(w.merged_in_window + 1, kMaxWorkerThreads);
    if (w.counted < w.threads) cores_dirty_ = true;
    // A worker's own clock: a NaN or a near-zero time would poison the smoothed rate.
    if (std::isfinite(wall_seconds) && wall_seconds >= 1e-3) {
        // Per-thread rate of this job, times the worker's threads, smoothed.
        const double rate = double(samples) / wall_seconds * std::max(w.threads, 1u);
        w.rate = w.rate == 0 ? rate : 0.8 * w.rate + 0.2 * rate;
    }
    w.unrecorded += samples;  // written by tick(), not once per merged job
}

void WorkerRegistry::note_failure(const std::string& name) {
    std::lock_guard lock(mutex_);
    if (const auto it = workers_.find(name); it != workers_.end()) ++it->second.failures;
}

bool WorkerRegistry::tick(int64_t now_ms, bool sweep_rows) {
    std::lock_guard lock(mutex_);
    bool any_lost = false;
    // Not a structured binding: the lambdas below copy the name, and C++17 (clang's,
    // for the fuzz build) cannot capture one.
    for (auto& entry : workers_) {
        const std::string& name = entry.first;
        WorkerEntry& w = entry.second;
        if (w.unrecorded > 0) {
            archive_.record_worker_samples(name, w.unrecorded, w.last_seen_ms);
            w.unrecorded = 0;
            w.stored_seen_ms = w.last_seen_ms;
        } else if (!w.lost &&
                   w.last_seen_ms - w.stored_seen_ms > limits_.forget_after.count() / 4) {
            // An idle worker's row is kept fresh, so that the sweep below takes only
            // workers gone.
            archive_.record_worker(name, w.threads, w.last_seen_ms);
            w.stored_seen_ms = w.last_seen_ms;
        }
        if (!w.lost && w.polling == 0 &&
            now_ms - w.last_seen_ms > limits_.lost_after.count()) {
            w.lost = true;
            set_alive(name, false);
            any_lost = true;
            events_.on_worker(EventKind::WorkerLost, name,
                              {log_number("last_seen_ms", w.last_seen_ms)});
            archive_.record_worker_lost(name);
        }
    }
    forget_silent_workers(now_ms);
    // Merges of a working window two windows ago stop counting, and leases taken or
    // ended since the last count are counted.
    count_cores(now_ms);
    // Rows of workers silent as long, those of an earlier run of the coordinator included
    // (it remembers no worker across a restart).
    if (sweep_rows)
        archive_.forget_workers_silent_since(now_ms - limits_.forget_after.count());
    return any_lost;
}

std::vector<WorkerStatus> WorkerRegistry::statuses(
    const std::map<std::string, std::vector<std::string>>& labels_by_link) const {
    std::lock_guard lock(mutex_);
    std::map<std::string, std::vector<std::string>> leases;  // by worker name
    for (const auto& [link, labels] : labels_by_link)
        if (const auto it = links_.find(link); it != links_.end())
            for (const std::string& label : labels)
                leases[it->second.worker].push_back(label);
    std::vector<WorkerStatus> out;
    for (const auto& [name, w] : workers_) {
        WorkerStatus st;
        st.name = name;
        st.threads = w.threads;
        if (auto it = leases.find(name); it != leases.end())
            st.leases = std::move(it->second);
        st.state = w.lost ? "lost" : (st.leases.empty() ? "idle" : "busy");
        st.samples_traced = w.samples;
        st.samples_per_second = w.lost ? 0 : w.rate;
        st.last_seen_ms = w.last_seen_ms;
        st.host = w.host;
        st.version = w.version;
        st.failures = w.failures;
        out.push_back(std::move(st));
    }
    return out;
}

}  // namespace aliquot
