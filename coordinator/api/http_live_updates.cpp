// The dashboard's live updates: what changed, published once by the broadcaster's
// thread, and the event streams that send it (EventHub between them, event_hub.h); a
// group of HttpServer's routes (http_server_impl.h).
#include "http_server_impl.h"

#include <algorithm>
#include <set>

#include "unix_millis.h"

namespace aliquot {

using nlohmann::json;

void HttpServer::Impl::snapshot(bool publish) {
    const std::vector<RenderInfo> renders = coordinator.list(options.max_list);
    json changed = json::array(), rounds = json::array();
    std::set<std::string> present;
    for (const RenderInfo& info : renders) {
        present.insert(info.id);
        const auto progress = progress_of(info);
        Seen now{info.state,
                 info.samples_done,
                 info.rounds_done,
                 info.error_estimate,
                 info.error_vs_reference,
                 progress ? progress->converged : 0};
        auto it = seen_renders.find(info.id);
        const uint32_t rounds_before = it == seen_renders.end() ? 0 : it->second.rounds;
        if (it != seen_renders.end() && it->second == now) continue;
        changed.push_back(render_summary(info, progress));
        if (info.rounds_done > rounds_before && publish) {
            if (auto all = coordinator.rounds(info.id)) {
                const size_t fresh =
                    std::min<size_t>(all->size(), info.rounds_done - rounds_before);
                for (size_t i = all->size() - fresh; i < all->size(); ++i) {
                    json r = http_api::round_json((*all)[i]);
                    r["id"] = info.id;
                    r["position"] = i;
                    rounds.push_back(std::move(r));
                }
            }
        }
        seen_renders[info.id] = now;
    }
    for (auto it = seen_renders.begin(); it != seen_renders.end();)
        it = present.count(it->first) ? std::next(it) : seen_renders.erase(it);

    const std::vector<WorkerStatus> workers = coordinator.workers();
    std::string key;
    uint64_t samples = 0;
    for (const WorkerStatus& w : workers) {
        key += w.name + '|' + w.state + '|' + std::to_string(w.threads) + '|';
        for (const std::string& l : w.leases) key += l + ',';
        key += '\n';
        samples += w.samples_traced;
    }
    const auto now = std::chrono::steady_clock::now();
    // Membership, state or leases at once; sample counters and rates every 2 s at
    // most.
    const bool workers_changed =
        key != seen_workers ||
        (samples != seen_worker_samples && now - workers_sent > std::chrono::seconds(2));
    seen_workers = key;
    if (!publish) {
        seen_worker_samples = samples;
        return;
    }
    if (!changed.empty())
        hub.publish(json_text(json{{"type", "render"}, {"renders", changed}}));
    if (!rounds.empty())
        hub.publish(json_text(json{{"type", "round"}, {"rounds", rounds}}));
    if (workers_changed) {
        seen_worker_samples = samples;
        workers_sent = now;
        json list = json::array();
        for (const WorkerStatus& w : workers) list.push_back(http_api::worker_json(w));
        hub.publish(json_text(
            {{"type", "workers"}, {"workers", list}, {"now_ms", unix_millis_now()}}));
    }
}

void HttpServer::Impl::publish_storage_warning() {
    std::string warning = coordinator.storage_warning();
    if (warning == seen_storage_warning) return;
    seen_storage_warning = warning;
    hub.publish(json_text(json{{"type", "storage"}, {"storage_warning", warning}}));
}

void HttpServer::Impl::broadcast() {
    uint64_t version = 0;
    while (!hub.stopping()) {
        // Short waits, so that shutting down never waits long for a quiet
        // coordinator.
        const uint64_t now =
            coordinator.wait_for_change(version, std::chrono::milliseconds(200));
        if (hub.stopping()) break;
        // Nothing in this thread may end the process: a failed update is logged.
        try {
            // The record's disk can fill or free up without any render changing.
            publish_storage_warning();
            if (now == version) continue;
            version = now;
            snapshot(true);
        } catch (const std::exception& e) {
            log_farm_error(std::string("live update failed: ") + e.what(), "http_error");
        }
        hub.pause(options.event_interval);
    }
}

void HttpServer::Impl::events(const httplib::Request& req, httplib::Response& res) {
    // A refused stream is told when to come back; the dashboard backs off further.
    Admission::Ticket ticket = streams.take(req.remote_addr);
    if (!ticket.place) {
        res.set_header("Retry-After", "10");
        res.set_header("Connection", "close");
        send_error(res, 503,
                   ticket.peer_share_full
                       ? "too many live-update streams are open from " + req.remote_addr +
                             " (at most " + std::to_string(streams.places_per_peer()) +
                             " from one address); try again later"
                       : "too many live-update streams are open (at most " +
                             std::to_string(options.max_event_streams) +
                             "); try again later");
        return;
    }
    Admission::Place slot = std::move(ticket.place);
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    // Each event must be taken in time, as an image is; one its client does not
    // read at all fills the sockets' buffers only after hours, so every stream also
    // ends after event_stream_life (the browser's EventSource opens another after
    // the `retry` below, and the dashboard fetches afresh).
    HttpFront::pace_current_response(std::nullopt);
    const auto ends = std::chrono::steady_clock::now() + options.event_stream_life;
    auto from = std::make_shared<uint64_t>(hub.next());
    auto greeted = std::make_shared<bool>(false);
    // The provider owns the slot: httplib destroys it with the response, however the
    // stream ends (client gone, write failed, server stopping).
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, from, greeted, slot, ends](size_t, httplib::DataSink& sink) {
            std::string out;
            if (!*greeted) {
                *greeted = true;
                out = "retry: 2000\n\ndata: " +
                      json_text({{"type", "hello"},
                                 {"now_ms", unix_millis_now()},
                                 {"storage_warning", coordinator.storage_warning()}}) +
                      "\n\n";
                return sink.write(out.data(), out.size());
            }
            std::vector<std::string> messages;
            bool missed = false;
            // Waits in short slices, looking between them whether the client is
            // still there (httplib's is_writable sees a closed peer), so a stream
            // whose client left gives its thread back promptly, not at the next
            // write.
            const auto idle_until =
                std::chrono::steady_clock::now() + std::chrono::seconds(15);
            for (;;) {
                if (std::chrono::steady_clock::now() >= ends ||
                    !hub.wait(*from, options.client_check_interval, messages, missed)) {
                    sink.done();
                    return true;
                }
                if (missed || !messages.empty()) break;
                if (!sink.is_writable()) return false;  // ends the connection
                if (std::chrono::steady_clock::now() >= idle_until) break;
            }
            if (missed) out += "data: {\"type\":\"resync\"}\n\n";
            for (const std::string& m : messages) out += "data: " + m + "\n\n";
            // A comment keeps proxies from closing an idle stream.
            if (out.empty()) out = ": idle\n\n";
            return sink.write(out.data(), out.size());
        });
}

void HttpServer::Impl::event_routes() {
    server.Get("/api/events", [this](const httplib::Request& req,
                                     httplib::Response& res) { events(req, res); });
}

}  // namespace aliquot
