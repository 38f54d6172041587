// RenderEvents: what happens to renders and workers, each event one line of the
// coordinator's structured log (log_line.h: text or JSON on stderr), and a render's own
// events kept as its trail: in memory while the render is, and in the run record
// (render_events table) for after. A trail keeps the first kKeepFirst and the last
// kKeepLast events of its render: a render of ten thousand rounds keeps 64, and says how
// many it dropped. The kinds and their spellings are here and nowhere else.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "log_line.h"
#include "render_session.h"

namespace aliquot {

class RecordBacklog;
class RunStore;

enum class EventKind {
    Submitted,
    Started,  // its first job was leased: it left the queue
    Resumed,  // a restarted coordinator took it up again
    RoundEnded,
    Finished,
    Failed,
    Cancelled,
    WorkerRegistered,
    WorkerLost,
    WorkerBlocklisted,  // kept off one render's jobs after failing them (FailurePolicy)
};

// "submitted", "started", "resumed", "round_ended", "finished", "failed", "cancelled",
// "worker_registered", "worker_lost", "worker_blocklisted".
std::string_view to_string(EventKind kind);
std::optional<EventKind> parse_event_kind(std::string_view text);

struct RenderEvent {
    std::string render_id;
    uint64_t seq = 0;  // within its render, from 0; a gap is events dropped
    int64_t at_ms = 0;
    EventKind kind = EventKind::Submitted;
    LogFields fields;  // besides the render's id
};

// Events of one render, in order.
struct EventPage {
    std::vector<RenderEvent> events;
    uint64_t omitted = 0;  // the render's events dropped from the middle of its trail
};

// Fields as a JSON object's text ({"round":3,"name":"a"}: numbers stay numbers), and
// back; the record, GetEvents and the HTTP API carry them so.
std::string fields_json(const LogFields& fields);
LogFields fields_of_json(const std::string& json);

// What a `submitted` event says of its render: name, scene, method, size, priority.
LogFields submitted_fields(const RenderSpec& spec);
// A round's: its number, samples in it and in all, seconds, error estimate.
LogFields round_fields(const RoundSummary& round);
// Finished, Failed or Cancelled, as the render ended; and what it says then (samples,
// rounds, seconds; why it failed).
EventKind end_event(RenderState state);
LogFields end_fields(const RenderSession& render);

class RenderEvents {
public:
    static constexpr size_t kKeepFirst = 16, kKeepLast = 48;

    // With a store, each render event is also written to it through `backlog`, in order
    // with the render's other records. Call before any event.
    void record_to(RunStore* store, RecordBacklog* backlog);

    // Logs the event and adds it to the render's trail.
    void on_render(EventKind kind, const std::string& render_id, LogFields fields = {});
    // Logs a worker's event (no trail: workers' events are not a render's).
    void on_worker(EventKind kind, const std::string& worker, LogFields fields = {});
    // A render taken up from the store: its numbering goes on after what the store has.
    void resume(const std::string& render_id);
    // The events of `render_id` numbered after `after_seq` (-1: from the first), at most
    // `limit`, from memory or else the store; nullopt for a render neither knows.
    std::optional<EventPage> read(const std::string& render_id, int64_t after_seq,
                                  size_t limit) const;
    // The render left memory (its trail is in the store) or was deleted.
    void forget(const std::string& render_id);
    // Renders with a trail in memory: for tests.
    size_t trails() const;

    // Where lines go: write_log_line, or a test's.
    std::function<void(std::string_view event, const LogFields& fields)> log =
        write_log_line;

private:
    struct Trail {
        std::vector<RenderEvent> first;  // up to kKeepFirst
        std::deque<RenderEvent> last;    // up to kKeepLast after those
        uint64_t next_seq = 0;
    };
    mutable std::mutex mutex_;  // a leaf: only the backlog's queue is taken under it
    std::map<std::string, Trail> trails_;
    RunStore* store_ = nullptr;
    RecordBacklog* backlog_ = nullptr;
};

}  // namespace aliquot
