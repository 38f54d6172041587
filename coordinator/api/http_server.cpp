#include "http_server.h"

#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "exr_io.h"
#include "http_api.h"
#include "http_session.h"
#include "scene_loader.h"
#include "store.h"

namespace aliquot {

using http_api::ApiError;
using nlohmann::json;

namespace {

// Live updates: the broadcaster publishes numbered messages, each event stream sends
// those it has not sent yet. A stream that falls further behind than the ring holds is
// told to resynchronise (fetch everything again) instead of being queued for without
// bound.
class EventHub {
public:
    void publish(std::string message) {
        {
            std::lock_guard lock(mutex_);
            ring_.emplace_back(next_++, std::move(message));
            if (ring_.size() > kRing) ring_.pop_front();
        }
        cv_.notify_all();
    }
    uint64_t next() {
        std::lock_guard lock(mutex_);
        return next_;
    }
    // Waits up to `timeout` for messages numbered `from` or later and appends them to
    // `out`, advancing `from`. Returns false once the hub has stopped.
    bool wait(uint64_t& from, std::chrono::milliseconds timeout,
              std::vector<std::string>& out, bool& missed) {
        std::unique_lock lock(mutex_);
        cv_.wait_for(lock, timeout, [&] { return stopping_ || next_ > from; });
        if (stopping_) return false;
        missed = !ring_.empty() && ring_.front().first > from;
        for (const auto& [seq, message] : ring_)
            if (seq >= from) out.push_back(message);
        from = next_;
        return true;
    }
    void stop() {
        {
            std::lock_guard lock(mutex_);
            stopping_ = true;
        }
        cv_.notify_all();
    }
    bool stopping() {
        std::lock_guard lock(mutex_);
        return stopping_;
    }
    // Sleeps `d` unless the hub stops first.
    void pause(std::chrono::milliseconds d) {
        std::unique_lock lock(mutex_);
        cv_.wait_for(lock, d, [&] { return stopping_; });
    }

private:
    static constexpr size_t kRing = 256;
    std::mutex mutex_;
    std::condition_variable cv_;
    std::deque<std::pair<uint64_t, std::string>> ring_;
    uint64_t next_ = 1;
    bool stopping_ = false;
};

// Every JSON this server sends: bytes that are not UTF-8 (a URL's %FF echoed in an error,
// a string cut mid-character) become U+FFFD instead of a throw from dump(), which outside
// a handler's try would end the process.
std::string json_text(const json& body) {
    return body.dump(-1, ' ', false, json::error_handler_t::replace);
}

void send_json(httplib::Response& res, const json& body, int status = 200) {
    res.status = status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(json_text(body), "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& message) {
    send_json(res, {{"error", message}}, status);
}

std::string content_type_of(const std::filesystem::path& p) {
    static const std::map<std::string, std::string> types = {
        {".md", "text/markdown; charset=utf-8"},
        {".txt", "text/plain; charset=utf-8"},
        {".csv", "text/csv; charset=utf-8"},
        {".json", "application/json"},
        {".png", "image/png"},
        {".jpg", "image/jpeg"},
        {".jpeg", "image/jpeg"},
        {".svg", "image/svg+xml"},
        {".html", "text/plain; charset=utf-8"},  // shown as source, never run as a page
    };
    const auto it = types.find(p.extension().string());
    return it == types.end() ? "" : it->second;
}

std::string first_heading(const std::filesystem::path& md) {
    std::ifstream in(md);
    std::string line;
    for (int n = 0; n < 40 && std::getline(in, line); ++n)
        if (line.rfind("# ", 0) == 0) return line.substr(2);
    return {};
}

// The server object: an SSLServer when the options name a certificate. SSLServer loads
// both files in its constructor and only says whether that worked, so the message names
// what to check.
std::unique_ptr<httplib::Server> make_server(const HttpOptions& o) {
    if (o.tls_cert.empty() && o.tls_key.empty())
        return std::make_unique<httplib::Server>();
    if (o.tls_cert.empty() || o.tls_key.empty())
        throw std::invalid_argument("http: a TLS certificate and its key go together");
    auto server =
        std::make_unique<httplib::SSLServer>(o.tls_cert.c_str(), o.tls_key.c_str());
    if (!server->is_valid())
        throw std::runtime_error(
            "http: cannot use TLS certificate " + o.tls_cert.string() + " with key " +
            o.tls_key.string() +
            " (unreadable, not PEM, or a key of another certificate)");
    return server;
}

std::string query(const httplib::Request& req, const std::string& name,
                  const std::string& fallback) {
    return req.has_param(name.c_str()) ? req.get_param_value(name.c_str()) : fallback;
}

}  // namespace

// The server's threads, and how many of them event streams may never take.
constexpr size_t kThreads = 32;
constexpr size_t kFreeThreads = 8;

struct HttpServer::Impl {
    Coordinator& coordinator;
    HttpOptions options;
    std::unique_ptr<httplib::Server> owned_server;  // Server, or SSLServer under TLS
    httplib::Server& server;
    const bool https;  // what the Origin of a same-site request starts with
    std::optional<http_api::HostPolicy> hosts;  // set in start(), once the port is known
    EventHub hub;
    std::thread listener, broadcaster;
    int port = 0;
    std::once_flag stopped;

    // What the broadcaster last told the browsers, to send only what changed.
    struct Seen {
        RenderState state = RenderState::Queued;
        uint64_t samples = 0;
        uint32_t rounds = 0;
        double error = -1, reference = -1;
        size_t converged = 0;
        bool operator==(const Seen&) const = default;
    };
    std::map<std::string, Seen> seen_renders;
    std::string seen_workers;
    uint64_t seen_worker_samples = 0;
    std::chrono::steady_clock::time_point workers_sent;

    Impl(Coordinator& c, HttpOptions o)
        : coordinator(c),
          options(std::move(o)),
          owned_server(make_server(options)),
          server(*owned_server),
          https(!options.tls_cert.empty()) {}

    // ---- renders ----

    std::optional<BucketProgress> progress_of(const RenderInfo& info) {
        // Only running renders: a finished one reports progress 1 and may live only in
        // the store, where its buckets cost a read of every round.
        if (is_terminal(info.state)) return std::nullopt;
        if (info.method != "dammertz") return std::nullopt;
        const auto b = coordinator.buckets(info.id);
        if (!b || b->empty()) return std::nullopt;
        return bucket_progress(*b, info.width, info.height);
    }

    RenderInfo render_or_404(const std::string& id) {
        if (id.size() > 64)
            throw ApiError(404, "no render '" + id.substr(0, 64) + "...'");
        std::optional<RenderInfo> info = coordinator.info(id);
        if (!info) throw ApiError(404, "no render '" + id + "'");
        return *info;
    }

    json list_renders(size_t limit) {
        json out = json::array();
        for (const RenderInfo& info : coordinator.list(limit))
            out.push_back(render_summary(info, progress_of(info)));
        return out;
    }

    json workers_json() {
        json out = json::array();
        for (const WorkerStatus& w : coordinator.workers())
            out.push_back(http_api::worker_json(w));
        return out;
    }

    // ---- live updates ----

    void snapshot(bool publish) {
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
            const uint32_t rounds_before =
                it == seen_renders.end() ? 0 : it->second.rounds;
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
            key != seen_workers || (samples != seen_worker_samples &&
                                    now - workers_sent > std::chrono::seconds(2));
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
            for (const WorkerStatus& w : workers)
                list.push_back(http_api::worker_json(w));
            hub.publish(json_text(
                {{"type", "workers"}, {"workers", list}, {"now_ms", unix_millis_now()}}));
        }
    }

    // Tells the browsers when writing the run record starts or stops failing.
    std::string seen_storage_warning;
    void publish_storage_warning() {
        std::string warning = coordinator.storage_warning();
        if (warning == seen_storage_warning) return;
        seen_storage_warning = warning;
        hub.publish(json_text(json{{"type", "storage"}, {"storage_warning", warning}}));
    }

    void broadcast() {
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
                std::fprintf(stderr, "http: live update failed: %s\n", e.what());
            }
            hub.pause(options.event_interval);
        }
    }

    // One open event stream: holds a slot of `max_event_streams` while it lives.
    class StreamSlot {
    public:
        explicit StreamSlot(Impl& impl) : impl_(impl) {}
        ~StreamSlot() {
            std::lock_guard lock(impl_.streams_mutex);
            --impl_.streams;
        }
        StreamSlot(const StreamSlot&) = delete;
        StreamSlot& operator=(const StreamSlot&) = delete;

    private:
        Impl& impl_;
    };
    std::mutex streams_mutex;
    size_t streams = 0;

    // EXR downloads encode the whole float image in memory (an 8192x8192 one with its
    // layers is over a gigabyte): a few at once, the others are told to come back.
    static constexpr int kMaxExrDownloads = 2;
    std::atomic<int> exr_downloads{0};

    std::shared_ptr<StreamSlot> take_stream_slot() {
        std::lock_guard lock(streams_mutex);
        if (streams >= options.max_event_streams) return nullptr;
        ++streams;
        return std::make_shared<StreamSlot>(*this);
    }

    void events(const httplib::Request&, httplib::Response& res) {
        // A refused stream is told when to come back; the dashboard backs off further.
        std::shared_ptr<StreamSlot> slot = take_stream_slot();
        if (!slot) {
            res.set_header("Retry-After", "10");
            res.set_header("Connection", "close");
            send_error(res, 503,
                       "too many live-update streams are open (at most " +
                           std::to_string(options.max_event_streams) +
                           "); try again later");
            return;
        }
        res.set_header("Cache-Control", "no-store");
        res.set_header("X-Accel-Buffering", "no");
        auto from = std::make_shared<uint64_t>(hub.next());
        auto greeted = std::make_shared<bool>(false);
        // The provider owns the slot: httplib destroys it with the response, however the
        // stream ends (client gone, write failed, server stopping).
        res.set_chunked_content_provider(
            "text/event-stream",
            [this, from, greeted, slot](size_t, httplib::DataSink& sink) {
                std::string out;
                if (!*greeted) {
                    *greeted = true;
                    out =
                        "retry: 2000\n\ndata: " +
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
                    if (!hub.wait(*from, options.client_check_interval, messages,
                                  missed)) {
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

    // ---- studies ----

    json list_studies() {
        namespace fs = std::filesystem;
        json out = json::array();
        for (const auto& [label, dir] : options.study_dirs) {
            std::error_code ec;
            if (!fs::is_directory(dir, ec)) continue;
            std::vector<fs::path> studies;
            for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
                if (e.is_directory()) studies.push_back(e.path());
            std::sort(studies.begin(), studies.end());
            for (const fs::path& s : studies) {
                std::vector<std::string> names;
                for (auto it = fs::recursive_directory_iterator(s, ec);
                     it != fs::recursive_directory_iterator() && names.size() < 200;
                     ++it) {
                    if (it.depth() > 2) it.disable_recursion_pending();
                    if (!it->is_regular_file() || content_type_of(it->path()).empty())
                        continue;
                    names.push_back(fs::relative(it->path(), s).generic_string());
                }
                std::sort(names.begin(), names.end());
                std::string report;
                for (const std::string& n : names)
                    if (n == "report.md" || (report.empty() && n.ends_with(".md") &&
                                             n.find('/') == std::string::npos))
                        report = n;
                // A study is a directory with a report; other output (renders, logs) is
                // not.
                if (report.empty()) continue;
                const std::string title = first_heading(s / report);
                out.push_back({{"source", label},
                               {"name", s.filename().string()},
                               {"title", title.empty() ? s.filename().string() : title},
                               {"report", report},
                               {"files", names}});
            }
        }
        return out;
    }

    void study_file(const std::string& label, const std::string& name,
                    const std::string& rel, httplib::Response& res) {
        namespace fs = std::filesystem;
        const auto source =
            std::find_if(options.study_dirs.begin(), options.study_dirs.end(),
                         [&](const auto& d) { return d.first == label; });
        if (source == options.study_dirs.end())
            throw ApiError(404, "no study source '" + label + "'");
        if (name.find("..") != std::string::npos || rel.find("..") != std::string::npos ||
            !fs::path(name).is_relative() || !fs::path(rel).is_relative())
            throw ApiError(400, "study paths must be relative and may not contain '..'");
        const auto missing = [&] {
            return ApiError(404, "no study file '" + name + "/" + rel + "'");
        };
        std::error_code ec;
        const fs::path root = fs::weakly_canonical(source->second / name, ec);
        if (ec || root.empty()) throw missing();
        const fs::path file = fs::weakly_canonical(root / rel, ec);
        if (ec || content_type_of(file).empty() || !fs::is_regular_file(file, ec))
            throw missing();
        // Inside the study's folder by path components, not by string prefix.
        const fs::path inside = file.lexically_relative(root);
        if (inside.empty() || *inside.begin() == "..") throw missing();
        const std::string type = content_type_of(file);
        std::ifstream in(file, std::ios::binary);
        std::ostringstream body;
        body << in.rdbuf();
        res.set_header("Cache-Control", "no-cache");
        res.set_content(body.str(), type.c_str());
    }

    // ---- routing ----

    // Runs a handler; every refusal becomes a JSON error with a 4xx status.
    template <typename Fn>
    httplib::Server::Handler guarded(Fn fn) {
        return [fn](const httplib::Request& req, httplib::Response& res) {
            try {
                fn(req, res);
            } catch (const ApiError& e) {
                send_error(res, e.status(), e.what());
            } catch (const MemoryBudgetError& e) {  // submit: try again later
                send_error(res, 429, e.what());
            } catch (const std::invalid_argument& e) {  // spec validation
                send_error(res, 400, e.what());
            } catch (const SceneError& e) {
                send_error(res, 400, e.what());
            } catch (const json::exception& e) {
                send_error(res, 400, std::string("malformed request: ") + e.what());
            } catch (const std::exception& e) {
                std::fprintf(stderr, "http: %s %s: %s\n", req.method.c_str(),
                             req.path.c_str(), e.what());
                send_error(res, 500, std::string("internal error: ") + e.what());
            }
        };
    }

    // Before any route, file or body: refuses requests another site's page could make
    // (docs/SECURITY.md, "Cross-site requests"). A refused request's body is never read,
    // so its connection is closed.
    httplib::Server::HandlerResponse refuse(httplib::Response& res, int status,
                                            const std::string& message) {
        res.set_header("Connection", "close");
        send_error(res, status, message);
        return httplib::Server::HandlerResponse::Handled;
    }
    httplib::Server::HandlerResponse cross_site_check(const httplib::Request& req,
                                                      httplib::Response& res) {
        // Probes (Docker, Kubernetes) name the container or pod by its IP or not at all;
        // /healthz answers {"ok": true} only, which tells a rebinding page nothing.
        if (req.path == "/healthz") return httplib::Server::HandlerResponse::Unhandled;
        const std::string host = req.get_header_value("Host");
        if (!hosts->allows(host))
            return refuse(res, 403,
                          "Host header \"" + host.substr(0, 100) +
                              "\" is not this server's (allowed: " + hosts->describe() +
                              "; add names with --allow-host)");
        const bool mutating =
            req.method != "GET" && req.method != "HEAD" && req.method != "OPTIONS";
        if (mutating && req.has_header("Origin") &&
            !http_api::origin_matches_host(req.get_header_value("Origin"), host, https))
            return refuse(res, 403,
                          "cross-origin request refused: Origin \"" +
                              req.get_header_value("Origin").substr(0, 100) +
                              "\" is not " + (https ? "https://" : "http://") + host);
        if (mutating &&
            !http_api::is_json_content_type(req.get_header_value("Content-Type")))
            return refuse(
                res, 415,
                "a " + req.method + " request must have Content-Type: application/json");
        return httplib::Server::HandlerResponse::Unhandled;
    }

    // After the cross-site checks, so that a foreign page learns nothing more from a 401
    // than from a 403. Only the client token opens the API.
    httplib::Server::HandlerResponse token_check(const httplib::Request& req,
                                                 httplib::Response& res) {
        if (!http_session::needs_token(req.method, req.path))
            return httplib::Server::HandlerResponse::Unhandled;
        const Access access = check_access(
            options.tokens,
            http_session::presented_token(req.get_header_value("Authorization"),
                                          req.get_header_value("Cookie")),
            Role::Client);
        if (access == Access::Granted) return httplib::Server::HandlerResponse::Unhandled;
        res.set_header("Connection", "close");  // its body is never read
        send_refusal(res, access);
        return httplib::Server::HandlerResponse::Handled;
    }

    // 401 with WWW-Authenticate (no or a wrong token) or 403 (the worker's), as JSON.
    static void send_refusal(httplib::Response& res, Access access) {
        if (access == Access::Unauthenticated)
            res.set_header("WWW-Authenticate", "Bearer");
        send_error(res, access == Access::Forbidden ? 403 : 401,
                   http_session::refusal_message(access));
    }

    void routes() {
        server.set_pre_routing_handler(
            [this](const httplib::Request& req, httplib::Response& res) {
                const auto cross_site = cross_site_check(req, res);
                if (cross_site == httplib::Server::HandlerResponse::Handled)
                    return cross_site;
                return token_check(req, res);
            });
        render_routes();
        session_routes();
        image_routes();
        other_routes();
        error_routes();
        dashboard_route();
    }

    // Renders: list, submit, read, cancel, change priority, delete, rounds.
    void render_routes() {
        server.Get(
            "/api/renders", guarded([this](const httplib::Request& req, auto& res) {
                const size_t limit = size_t(http_api::number_param(
                    "limit", query(req, "limit", "200"), 1, double(options.max_list)));
                send_json(res, {{"renders", list_renders(limit)},
                                {"now_ms", unix_millis_now()},
                                {"storage_warning", coordinator.storage_warning()}});
            }));
        server.Post("/api/renders",
                    guarded([this](const httplib::Request& req, auto& res) {
                        RenderSpec spec = http_api::parse_render_request(req.body);
                        const std::string id = coordinator.submit(std::move(spec));
                        const RenderInfo info = render_or_404(id);
                        res.set_header("Location", "/api/renders/" + id);
                        send_json(res, render_detail(info, progress_of(info)), 201);
                    }));
        server.Get(R"(/api/renders/([^/]+))",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const RenderInfo info = render_or_404(req.matches[1]);
                       json detail = render_detail(info, progress_of(info));
                       detail["storage_warning"] = coordinator.storage_warning();
                       send_json(res, detail);
                   }));
        server.Post(R"(/api/renders/([^/]+)/cancel)",
                    guarded([this](const httplib::Request& req, auto& res) {
                        http_api::parse_cancel_request(req.body);
                        render_or_404(req.matches[1]);
                        const auto info = coordinator.cancel(req.matches[1]);
                        if (!info)
                            throw ApiError(404,
                                           "no render '" + req.matches[1].str() + "'");
                        send_json(res, render_detail(*info));
                    }));
        server.Patch(
            R"(/api/renders/([^/]+))",
            guarded([this](const httplib::Request& req, auto& res) {
                const int32_t priority = http_api::parse_priority_request(req.body);
                std::optional<RenderInfo> info;
                try {
                    info = coordinator.set_priority(req.matches[1], priority);
                } catch (const RenderFinished& e) {
                    throw ApiError(409, e.what());
                }
                if (!info)
                    throw ApiError(404, "no render '" + req.matches[1].str() + "'");
                send_json(res, render_detail(*info, progress_of(*info)));
            }));
        server.Delete(R"(/api/renders/([^/]+))",
                      guarded([this](const httplib::Request& req, auto& res) {
                          const std::string id = req.matches[1];
                          switch (coordinator.remove(id)) {
                              case Coordinator::Removal::Removed:
                                  res.status = 204;
                                  return;
                              case Coordinator::Removal::Unknown:
                                  throw ApiError(404, "no render '" + id + "'");
                              case Coordinator::Removal::Unfinished:
                                  throw ApiError(409, "render '" + id +
                                                          "' has not finished; cancel "
                                                          "it first");
                          }
                      }));
        server.Get(
            R"(/api/renders/([^/]+)/rounds)",
            guarded([this](const httplib::Request& req, auto& res) {
                const std::string id = req.matches[1];
                const auto since = size_t(
                    http_api::number_param("since", query(req, "since", "0"), 0, 1e12));
                const auto limit = size_t(http_api::number_param(
                    "limit", query(req, "limit", "1000"), 1, 1000));
                const auto all = coordinator.rounds(id);
                if (!all) throw ApiError(404, "no render '" + id + "'");
                json rows = json::array();
                const size_t end = std::min(all->size(), since + limit);
                for (size_t i = since; i < end; ++i)
                    rows.push_back(http_api::round_row((*all)[i]));
                send_json(res, {{"id", id},
                                {"columns", http_api::kRoundColumns},
                                {"since", since},
                                {"rows", rows},
                                {"count", all->size()},
                                {"next", end < all->size() ? json(end) : json(nullptr)}});
            }));
    }

    // The dashboard's sign-in: the session cookie carries the client token (docs/API.md,
    // "Authentication"). GET needs the token like every route; POST and DELETE do not.
    void session_routes() {
        server.Get("/api/session", [](const httplib::Request&, httplib::Response& res) {
            send_json(res, {{"signed_in", true}});
        });
        server.Post(
            "/api/session", guarded([this](const httplib::Request& req, auto& res) {
                const std::string token = http_session::parse_sign_in_request(req.body);
                const Access access = check_access(options.tokens, token, Role::Client);
                if (access == Access::Granted) {
                    res.set_header("Set-Cookie",
                                   http_session::sign_in_cookie(token, https));
                    send_json(res, {{"ok", true}});
                    return;
                }
                send_refusal(res, access);
            }));
        server.Delete(
            "/api/session", [this](const httplib::Request&, httplib::Response& res) {
                res.set_header("Set-Cookie", http_session::sign_out_cookie(https));
                send_json(res, {{"ok", true}});
            });
    }

    // What the dashboard draws of one render: preview, heat maps, buckets.
    void image_routes() {
        server.Get(R"(/api/renders/([^/]+)/preview\.png)",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const std::string id = req.matches[1];
                       const double exposure = http_api::number_param(
                           "exposure", query(req, "exposure", "0"), -20, 20);
                       const auto size = uint32_t(http_api::number_param(
                           "size", query(req, "size", "1024"), 16, 8192));
                       render_or_404(id);
                       const std::optional<Image> image = coordinator.image(id, false);
                       if (!image)
                           throw ApiError(404, "render '" + id + "' has no image yet");
                       res.set_header("Cache-Control", "no-store");
                       res.set_content(http_api::preview_png(*image, exposure, size),
                                       "image/png");
                   }));
        server.Get(
            R"(/api/renders/([^/]+)/image\.exr)",
            guarded([this](const httplib::Request& req, auto& res) {
                const std::string id = req.matches[1];
                const std::string aovs = query(req, "aovs", "0");
                if (aovs != "0" && aovs != "1")
                    throw ApiError(400, "'aovs' must be 0 or 1, got \"" + aovs + "\"");
                render_or_404(id);
                if (++exr_downloads > kMaxExrDownloads) {
                    --exr_downloads;
                    res.set_header("Retry-After", "5");
                    throw ApiError(503, "too many EXR downloads at once (at most " +
                                            std::to_string(kMaxExrDownloads) +
                                            "); try again later");
                }
                struct Release {
                    std::atomic<int>& n;
                    ~Release() { --n; }
                } release{exr_downloads};
                const std::optional<Image> image = coordinator.image(id, aovs == "1");
                if (!image) throw ApiError(404, "render '" + id + "' has no image yet");
                res.set_header("Cache-Control", "no-store");
                res.set_header("Content-Disposition",
                               "attachment; filename=\"" + id + ".exr\"");
                // OpenEXR's own name for its type; not compressed again (ZIP inside).
                res.set_content(encode_exr(*image), "image/x-exr");
            }));
        server.Get(R"(/api/renders/([^/]+)/maps)",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const std::string id = req.matches[1];
                       const std::string kind = query(req, "kind", "spp");
                       if (kind != "spp" && kind != "error")
                           throw ApiError(
                               400, "'kind' must be spp or error, got \"" + kind + "\"");
                       const auto size = uint32_t(http_api::number_param(
                           "size", query(req, "size", "256"), 8, 256));
                       render_or_404(id);
                       const std::optional<Image> image = coordinator.image(id, true);
                       if (!image)
                           throw ApiError(404, "render '" + id + "' has no image yet");
                       const auto map_kind = kind == "spp" ? http_api::MapKind::Spp
                                                           : http_api::MapKind::Error;
                       json map = http_api::pixel_map(*image, map_kind, size);
                       map["id"] = id;
                       send_json(res, map);
                   }));
        server.Get(R"(/api/renders/([^/]+)/buckets)",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const std::string id = req.matches[1];
                       const RenderInfo info = render_or_404(id);
                       const auto buckets = coordinator.buckets(id);
                       if (!buckets) throw ApiError(404, "no render '" + id + "'");
                       const auto p = bucket_progress(*buckets, info.width, info.height);
                       send_json(res, {{"id", id},
                                       {"width", info.width},
                                       {"height", info.height},
                                       {"converged", p.converged},
                                       {"converged_area", p.converged_area},
                                       {"buckets", http_api::buckets_json(*buckets)}});
                   }));
    }

    // Health, workers, scenes, live events, studies.
    void other_routes() {
        server.Get("/healthz", [](const httplib::Request&, httplib::Response& res) {
            send_json(res, {{"ok", true}});
        });
        // Prometheus scrapes with the client token as a bearer (docs/API.md).
        if (options.metrics)
            server.Get("/metrics", guarded([this](const httplib::Request&, auto& res) {
                           res.set_header("Cache-Control", "no-store");
                           res.set_content(options.metrics->scrape(),
                                           FarmMetrics::kContentType);
                       }));
        server.Get("/api/workers", guarded([this](const httplib::Request&, auto& res) {
                       send_json(res, {{"workers", workers_json()},
                                       {"now_ms", unix_millis_now()}});
                   }));
        server.Get("/api/scenes", guarded([](const httplib::Request&, auto& res) {
                       send_json(res, {{"scenes", builtin_scene_names()},
                                       {"methods", submittable_methods()},
                                       {"defaults", StrategyParams{}}});
                   }));
        server.Get("/api/events", [this](const httplib::Request& req,
                                         httplib::Response& res) { events(req, res); });
        server.Get("/api/studies", guarded([this](const httplib::Request&, auto& res) {
                       send_json(res, {{"studies", list_studies()}});
                   }));
        server.Get(R"(/api/studies/([^/]+)/([^/]+)/(.+))",
                   guarded([this](const httplib::Request& req, auto& res) {
                       study_file(req.matches[1], req.matches[2], req.matches[3], res);
                   }));
    }

    void error_routes() {
        // Whatever else went wrong (no such route, a body too large, a request httplib
        // could not parse) still answers JSON with a message.
        server.set_error_handler(httplib::Server::HandlerWithResponse(
            [](const httplib::Request& req, httplib::Response& res) {
                if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
                std::string message = "no such endpoint: " + req.method + " " + req.path;
                if (res.status == 413)
                    message = "request body too large";
                else if (res.status == 400)
                    message = "malformed HTTP request";
                else if (res.status != 404)
                    message = "request refused (HTTP " + std::to_string(res.status) + ")";
                send_error(res, res.status, message);
                return httplib::Server::HandlerResponse::Handled;
            }));
        server.set_exception_handler(
            [](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
                send_error(res, 500, "internal error");
            });
    }

    // The built dashboard, or a page saying how to build it.
    void dashboard_route() {
        namespace fs = std::filesystem;
        std::error_code ec;
        if (!options.web_dir.empty() && fs::exists(options.web_dir / "index.html", ec)) {
            server.set_mount_point("/", options.web_dir.string());
        } else {
            const std::string where =
                options.web_dir.empty() ? "(none given)" : options.web_dir.string();
            server.Get("/", [where](const httplib::Request&, httplib::Response& res) {
                res.set_content(
                    "<!doctype html><title>Aliquot</title><p>The dashboard is not built "
                    "(looked in " +
                        where +
                        "): run <code>web/build.sh</code>, or pass "
                        "<code>--web DIR</code>. The JSON API is at <a "
                        "href=\"/api/renders\">"
                        "/api/renders</a>.",
                    "text/html");
            });
        }
    }

    void start(const std::string& address) {
        // A usable token is also one the session cookie carries as it is (RFC 6750's
        // b64token alphabet has no ; , " \ or %).
        check_tokens(options.tokens);
        const size_t colon = address.rfind(':');
        if (colon == std::string::npos)
            throw std::runtime_error("http: address must be host:port, got \"" + address +
                                     "\"");
        std::string host = address.substr(0, colon);
        if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
            host = host.substr(1, host.size() - 2);
        if (host.empty()) host = "0.0.0.0";
        int wanted = -1;
        try {
            size_t used = 0;
            wanted = std::stoi(address.substr(colon + 1), &used);
            if (used != address.size() - colon - 1) wanted = -1;
        } catch (const std::exception&) {
        }
        if (wanted < 0 || wanted > 65535)
            throw std::runtime_error("http: bad port in \"" + address + "\"");

        // Event streams hold a thread each and browsers keep a few idle connections open;
        // at most max_event_streams of the threads go to streams.
        if (options.max_event_streams + kFreeThreads > kThreads)
            throw std::invalid_argument(
                "http: at most " + std::to_string(kThreads - kFreeThreads) +
                " event streams, so that the server keeps threads for other requests");
        server.new_task_queue = [] { return new httplib::ThreadPool(kThreads); };
        server.set_payload_max_length(1 << 20);
        server.set_keep_alive_timeout(5);
        http_api::HostPolicy(host, wanted,
                             options.allowed_hosts);  // throws on a bad entry
        routes();
        if (wanted == 0) {
            port = server.bind_to_any_port(host);
            if (port <= 0) throw std::runtime_error("http: cannot listen on " + address);
        } else {
            if (!server.bind_to_port(host, wanted))
                throw std::runtime_error("http: cannot listen on " + address);
            port = wanted;
        }
        hosts.emplace(host, port, options.allowed_hosts);
        snapshot(false);  // later updates say what changed since now
        seen_storage_warning = coordinator.storage_warning();
        listener = std::thread([this] { server.listen_after_bind(); });
        broadcaster = std::thread([this] { broadcast(); });
    }

    void stop() {
        std::call_once(stopped, [this] {
            hub.stop();
            server.stop();
            if (listener.joinable()) listener.join();
            if (broadcaster.joinable()) broadcaster.join();
        });
    }
};

HttpServer::HttpServer(Coordinator& coordinator, const std::string& address,
                       HttpOptions options)
    : impl_(std::make_unique<Impl>(coordinator, std::move(options))) {
    impl_->start(address);
}

HttpServer::~HttpServer() { shutdown(); }

int HttpServer::port() const { return impl_->port; }

void HttpServer::shutdown() { impl_->stop(); }

}  // namespace aliquot
