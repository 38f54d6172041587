#include "render_events.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <nlohmann/json.hpp>

#include "record_backlog.h"
#include "store.h"

namespace aliquot {

namespace {

constexpr std::array<std::pair<EventKind, std::string_view>, 10> kSpellings = {{
    {EventKind::Submitted, "submitted"},
    {EventKind::Started, "started"},
    {EventKind::Resumed, "resumed"},
    {EventKind::RoundEnded, "round_ended"},
    {EventKind::Finished, "finished"},
    {EventKind::Failed, "failed"},
    {EventKind::Cancelled, "cancelled"},
    {EventKind::WorkerRegistered, "worker_registered"},
    {EventKind::WorkerLost, "worker_lost"},
    {EventKind::WorkerBlocklisted, "worker_blocklisted"},
}};

int64_t now_ms() {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

}  // namespace

// Ordered: a line reads in the order its event gave its fields (round before samples).
std::string fields_json(const LogFields& fields) {
    nlohmann::ordered_json j = nlohmann::ordered_json::object();
    for (const LogField& f : fields) {
        if (f.number)
            j[f.key] = nlohmann::ordered_json::parse(f.value, nullptr, false);
        else
            j[f.key] = f.value;
    }
    // A worker's name is the network's: bytes that are not UTF-8 become U+FFFD.
    return j.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

LogFields fields_of_json(const std::string& json) {
    LogFields fields;
    const nlohmann::ordered_json j = nlohmann::ordered_json::parse(json, nullptr, false);
    if (!j.is_object()) return fields;
    for (const auto& [key, value] : j.items()) {
        if (value.is_string())
            fields.push_back(log_text(key, value.get<std::string>()));
        else
            fields.push_back({key, value.dump(), true});
    }
    return fields;
}

std::string_view to_string(EventKind kind) {
    for (const auto& [k, text] : kSpellings)
        if (k == kind) return text;
    return "unknown";
}

std::optional<EventKind> parse_event_kind(std::string_view text) {
    for (const auto& [k, spelling] : kSpellings)
        if (spelling == text) return k;
    return std::nullopt;
}

LogFields submitted_fields(const RenderSpec& spec) {
    return {log_text("name", spec.name),
            log_text("scene", spec.scene_name),
            log_text("method", spec.strategy.method),
            log_number("width", int64_t(spec.width)),
            log_number("height", int64_t(spec.height)),
            log_number("priority", int64_t(spec.priority))};
}

LogFields round_fields(const RoundSummary& round) {
    return {log_number("round", int64_t(round.index)),
            log_number("samples", int64_t(round.samples_in_round)),
            log_number("samples_done", int64_t(round.samples_total)),
            log_number("seconds", round.seconds),
            log_number("error_estimate", round.error_estimate)};
}

EventKind end_event(RenderState state) {
    if (state == RenderState::Failed) return EventKind::Failed;
    if (state == RenderState::Cancelled) return EventKind::Cancelled;
    return EventKind::Finished;
}

LogFields end_fields(const RenderSession& render) {
    LogFields fields = {
        log_number("samples_done", int64_t(render.merged().total_samples())),
        log_number("rounds", int64_t(render.rounds_done())),
        log_number("seconds", render.seconds())};
    if (!render.error().empty()) fields.push_back(log_text("error", render.error()));
    return fields;
}

void RenderEvents::record_to(RunStore* store, RecordBacklog* backlog) {
    std::lock_guard lock(mutex_);
    store_ = store;
    backlog_ = backlog;
}

void RenderEvents::on_render(EventKind kind, const std::string& render_id,
                             LogFields fields) {
    RenderEvent e{render_id, 0, now_ms(), kind, std::move(fields)};
    {
        std::lock_guard lock(mutex_);
        Trail& trail = trails_[render_id];
        e.seq = trail.next_seq++;
        if (trail.first.size() < kKeepFirst) {
            trail.first.push_back(e);
        } else {
            trail.last.push_back(e);
            if (trail.last.size() > kKeepLast) trail.last.pop_front();
        }
        if (store_ && backlog_) {
            RenderEventRecord rec{render_id, int64_t(e.seq), e.at_ms,
                                  std::string(to_string(kind)), fields_json(e.fields)};
            backlog_->submit("record event " + std::to_string(e.seq) + " of " + render_id,
                             [store = store_, rec] {
                                 try {
                                     store->add_render_event(rec, kKeepFirst, kKeepLast);
                                 } catch (const StoreError& error) {
                                     // The render's row is gone (deleted meanwhile):
                                     // nothing to keep. Any other failure (a full disk)
                                     // is the backlog's to retry.
                                     if ((error.sqlite_code() & 0xff) != 19)
                                         throw;  // CONSTRAINT
                                 }
                             });
        }
    }
    LogFields line;
    line.reserve(e.fields.size() + 1);
    line.push_back(log_text("render", render_id));
    line.insert(line.end(), e.fields.begin(), e.fields.end());
    log(to_string(kind), line);
}

void RenderEvents::on_worker(EventKind kind, const std::string& worker,
                             LogFields fields) {
    fields.insert(fields.begin(), log_text("worker", worker));
    log(to_string(kind), fields);
}

void RenderEvents::resume(const std::string& render_id) {
    std::lock_guard lock(mutex_);
    if (!store_) return;
    // The store's trail stays there; the one in memory goes on from its numbering.
    const int64_t last = store_->render_event_span(render_id).second;
    Trail& trail = trails_[render_id];
    trail.next_seq = std::max<uint64_t>(trail.next_seq, uint64_t(last + 1));
}

std::optional<EventPage> RenderEvents::read(const std::string& render_id,
                                            int64_t after_seq, size_t limit) const {
    EventPage page;
    int64_t stored_last = -1;
    RunStore* store = nullptr;
    bool in_memory = false;
    {
        std::lock_guard lock(mutex_);
        store = store_;
        in_memory = trails_.count(render_id) > 0;
    }
    // With a store, it is the truth: a render that left memory, and what a resumed one
    // had before; memory adds only what the backlog has not written yet. Read off the
    // lock: the store may be slow.
    if (store) {
        const auto [count, last] = store->render_event_span(render_id);
        if (count == 0 && !in_memory && !store->get_render(render_id))
            return std::nullopt;
        for (const RenderEventRecord& rec :
             store->render_events(render_id, after_seq, limit)) {
            const std::optional<EventKind> kind = parse_event_kind(rec.kind);
            if (!kind) continue;  // written by a newer coordinator
            page.events.push_back({rec.render_id, uint64_t(rec.seq), rec.at_ms, *kind,
                                   fields_of_json(rec.fields_json)});
        }
        page.omitted = uint64_t(last + 1 - count);
        stored_last = last;
    }
    std::lock_guard lock(mutex_);
    const auto it = trails_.find(render_id);
    if (it == trails_.end()) {
        if (store) return page;
        return std::nullopt;
    }
    const Trail& trail = it->second;
    const int64_t from = std::max(after_seq, stored_last);
    auto take = [&](const RenderEvent& e) {
        if (int64_t(e.seq) > from && page.events.size() < limit) page.events.push_back(e);
    };
    for (const RenderEvent& e : trail.first) take(e);
    for (const RenderEvent& e : trail.last) take(e);
    if (!store) page.omitted = trail.next_seq - trail.first.size() - trail.last.size();
    return page;
}

void RenderEvents::forget(const std::string& render_id) {
    std::lock_guard lock(mutex_);
    trails_.erase(render_id);
}

size_t RenderEvents::trails() const {
    std::lock_guard lock(mutex_);
    return trails_.size();
}

}  // namespace aliquot
