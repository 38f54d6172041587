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

#include "admission.h"
#include "exr_io.h"
#include "farm_log.h"
#include "http_api.h"
#include "http_front.h"
#include "http_session.h"
#include "render_state.h"
#include "scene_loader.h"
#include "shown_id.h"
#include "stored_image.h"
#include "strategy_parameters.h"
#include "thumbnail_cache.h"
#include "unix_millis.h"

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

// A name of the request (a render id, a study's path) as an error message quotes it:
// bounded, printable.
std::string quoted_id(const std::string& id) { return "'" + shown_id(id) + "'"; }

void send_error(httplib::Response& res, int status, const std::string& message) {
    send_json(res, {{"error", message}}, status);
}

// Sends `body`, made by an image route, keeping `place` until it is sent or cut: the
// body is what the place bounds, and a slow reader holds both until the pace it must
// keep (FrontLimits::min_read_rate) cuts it.
void send_image(httplib::Response& res, std::string body, const std::string& type,
                Admission::Place place) {
    HttpFront::pace_current_response(body.size());
    if (body.empty()) return res.set_content("", type);
    auto held = std::make_shared<const std::string>(std::move(body));
    res.set_content_provider(
        held->size(), type,
        [held, place](size_t offset, size_t length, httplib::DataSink& sink) {
            return offset <= held->size() &&
                   sink.write(held->data() + offset,
                              std::min(length, held->size() - offset));
        });
}

// Sends the file at `path` as it is read, 1 MiB at a time: the response holds one chunk,
// never the file, and keeps `place` until it is sent or cut, its reader paced as
// send_image's. The file is opened here (a missing one is ApiError 404); one renamed or
// deleted meanwhile is still read whole.
void send_file(httplib::Response& res, const std::filesystem::path& path,
               const std::string& type, Admission::Place place) {
    constexpr size_t kChunk = 1 << 20;
    auto in = std::make_shared<std::ifstream>(path, std::ios::binary | std::ios::ate);
    if (!*in) throw ApiError(404, "no file " + path.filename().string());
    const auto size = size_t(in->tellg());
    HttpFront::pace_current_response(size);
    if (size == 0) return res.set_content("", type);
    auto buffer = std::make_shared<std::vector<char>>(std::min(size, kChunk));
    res.set_content_provider(
        size, type,
        [in, buffer, place](size_t offset, size_t length, httplib::DataSink& sink) {
            // Nothing may throw out of a provider: it runs on a server thread, outside
            // any handler's try. A read that falls short cuts the response.
            try {
                const size_t n = std::min(length, buffer->size());
                in->seekg(std::streamoff(offset));
                in->read(buffer->data(), std::streamsize(n));
                if (size_t(in->gcount()) != n) return false;
                return sink.write(buffer->data(), n);
            } catch (...) {
                return false;
            }
        });
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

// httplib's listener hands each accepted socket to its TaskQueue as a job that calls
// process_and_close_socket. This queue runs the job at once, and FrontedServer's
// process_and_close_socket gives the socket to the front: the listener never waits, and
// no thread is spent on a connection until its request has arrived (http_front.h).
class HandToFront : public httplib::TaskQueue {
public:
    void enqueue(std::function<void()> job) override { job(); }
    void shutdown() override {}
};

// What the HTTP server needs of httplib's server besides its routes: serving one request
// the front has read.
class FrontedRequests {
public:
    virtual ~FrontedRequests() = default;
    virtual bool serve(FrontConnection& connection, bool close, bool& closed) = 0;
    virtual void deepen_backlog() = 0;
    HttpFront* front = nullptr;  // set before the server listens
};

// httplib's Server or SSLServer with the front before it. httplib declares
// process_and_close_socket virtual (SSLServer overrides it too), and process_request
// protected: a subclass may serve a request over any Stream.
template <class Base>
class FrontedServer : public Base, public FrontedRequests {
public:
    using Base::Base;
    bool serve(FrontConnection& connection, bool close, bool& closed) override {
        return this->process_request(
            connection, close, closed,
            [&connection](httplib::Request& req) { req.ssl = connection.ssl(); });
    }

    // httplib listens with a backlog of 5, compiled in: a burst of connections (a
    // browser opens six at once) overflows it and each one over waits a second or more
    // for its SYN to be sent again. Listening again on the bound socket sets a deeper
    // one.
    void deepen_backlog() override { ::listen(this->svr_sock_, SOMAXCONN); }

private:
    bool process_and_close_socket(socket_t sock) override {
        front->admit(sock);
        return true;
    }
};

struct MadeServer {
    std::unique_ptr<httplib::Server> server;
    FrontedRequests* requests = nullptr;
    SSL_CTX* tls = nullptr;  // the SSLServer's, null for plain HTTP
};

// The server object: an SSLServer when the options name a certificate. SSLServer loads
// both files in its constructor and only says whether that worked, so the message names
// what to check.
MadeServer make_server(const HttpOptions& o) {
    MadeServer made;
    if (o.tls_cert.empty() && o.tls_key.empty()) {
        auto server = std::make_unique<FrontedServer<httplib::Server>>();
        made.requests = server.get();
        made.server = std::move(server);
        return made;
    }
    if (o.tls_cert.empty() || o.tls_key.empty())
        throw std::invalid_argument("http: a TLS certificate and its key go together");
    auto server = std::make_unique<FrontedServer<httplib::SSLServer>>(o.tls_cert.c_str(),
                                                                      o.tls_key.c_str());
    if (!server->is_valid())
        throw std::runtime_error(
            "http: cannot use TLS certificate " + o.tls_cert.string() + " with key " +
            o.tls_key.string() +
            " (unreadable, not PEM, or a key of another certificate)");
    made.tls = server->ssl_context();
    made.requests = server.get();
    made.server = std::move(server);
    return made;
}

bool iequals(std::string_view a, std::string_view b) {
    return a.size() == b.size() &&
           std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower((unsigned char)x) == std::tolower((unsigned char)y);
           });
}

std::string query(const httplib::Request& req, const std::string& name,
                  const std::string& fallback) {
    return req.has_param(name.c_str()) ? req.get_param_value(name.c_str()) : fallback;
}

}  // namespace

// How many of the server's threads (FrontLimits::threads) event streams may never take.
constexpr size_t kFreeThreads = 8;

struct HttpServer::Impl {
    Coordinator& coordinator;
    HttpOptions options;
    MadeServer made;  // Server, or SSLServer under TLS
    httplib::Server& server;
    const bool https;  // what the Origin of a same-site request starts with
    std::optional<http_api::HostPolicy> hosts;  // set in start(), once the port is known
    BrowserSessions sessions;
    std::string cookie_name;           // set in start(), once the port is known
    std::unique_ptr<HttpFront> front;  // set in start()
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
          made(make_server(options)),
          server(*made.server),
          https(!options.tls_cert.empty()),
          sessions(options.sessions) {}

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
        // No id the coordinator issues is longer: a longer one is not looked up.
        if (id.size() > 64) throw ApiError(404, "no render " + quoted_id(id));
        std::optional<RenderInfo> info = coordinator.info(id);
        if (!info) throw ApiError(404, "no render " + quoted_id(id));
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
                log_farm_error(std::string("live update failed: ") + e.what(),
                               "http_error");
            }
            hub.pause(options.event_interval);
        }
    }

    // Event streams open at once (each holds a thread while it lives).
    Admission streams{options.max_event_streams, options.max_event_streams_per_peer};

    // Requests that make or send an image, at once: each may hold a copy of a render's
    // image and its encoding (docs/SECURITY.md, "HTTP image routes").
    Admission image_requests{options.max_image_requests,
                             options.max_image_requests_per_peer};

    // The renders list's thumbnails: at most this many pixels on a side, and made again
    // only when a render changed (ThumbnailCache), for as many renders as a list shows.
    static constexpr uint32_t kThumbnailSide = 96;
    ThumbnailCache thumbnails{1000};

    Image image_or_404(const std::string& id, bool aovs) {
        std::optional<Image> image = coordinator.image(id, aovs);
        if (!image) throw ApiError(404, "render " + quoted_id(id) + " has no image yet");
        return std::move(*image);
    }

    // A render in memory's thumbnail is made straight from its sums; a stored one's from
    // its EXR, once (a finished render's version does not change).
    std::string thumbnail_png(const std::string& id) {
        std::string png;
        if (coordinator.read_sums(id, [&](const Accumulator& sums) {
                png = http_api::thumbnail_png(sums, kThumbnailSide);
            }))
            return png;
        return http_api::preview_png(image_or_404(id, false), 0, kThumbnailSide);
    }

    // A place among image_requests, or ApiError 503 with Retry-After.
    Admission::Place admit_image(const httplib::Request& req, httplib::Response& res) {
        Admission::Ticket ticket = image_requests.take(req.remote_addr);
        if (!ticket.place) {
            res.set_header("Retry-After", "2");
            throw ApiError(
                503, ticket.peer_share_full
                         ? "too many image requests at once from " + req.remote_addr +
                               " (previews, thumbnails, maps and EXR downloads "
                               "together, at most " +
                               std::to_string(image_requests.places_per_peer()) +
                               " from one address); try again later"
                         : "too many image requests at once (previews, thumbnails, "
                           "maps and EXR downloads together, at most " +
                               std::to_string(image_requests.places()) +
                               "); try again later");
        }
        if (options.image_admitted) options.image_admitted();
        return std::move(ticket.place);
    }

    void events(const httplib::Request& req, httplib::Response& res) {
        // A refused stream is told when to come back; the dashboard backs off further.
        Admission::Ticket ticket = streams.take(req.remote_addr);
        if (!ticket.place) {
            res.set_header("Retry-After", "10");
            res.set_header("Connection", "close");
            send_error(res, 503,
                       ticket.peer_share_full
                           ? "too many live-update streams are open from " +
                                 req.remote_addr + " (at most " +
                                 std::to_string(streams.places_per_peer()) +
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
                    if (std::chrono::steady_clock::now() >= ends ||
                        !hub.wait(*from, options.client_check_interval, messages,
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
            throw ApiError(404, "no study source " + quoted_id(label));
        if (name.find("..") != std::string::npos || rel.find("..") != std::string::npos ||
            !fs::path(name).is_relative() || !fs::path(rel).is_relative())
            throw ApiError(400, "study paths must be relative and may not contain '..'");
        const auto missing = [&] {
            return ApiError(404, "no study file " + quoted_id(name + "/" + rel));
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
                log_farm_error(req.method + " " + req.path + ": " + e.what(),
                               "http_error");
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

    // httplib inflates a gzip or brotli body before any handler sees it, and its size
    // limit counts the compressed bytes: 1 MB of gzip became 1000 MiB, before the token
    // was looked at. Nothing the API takes is sent compressed, so no compressed body is
    // accepted, refused before it is read.
    httplib::Server::HandlerResponse encoding_check(const httplib::Request& req,
                                                    httplib::Response& res) {
        const auto [first, last] = req.headers.equal_range("Content-Encoding");
        for (auto it = first; it != last; ++it) {
            std::string_view coding = it->second;
            while (!coding.empty() && (coding.front() == ' ' || coding.front() == '\t'))
                coding.remove_prefix(1);
            while (!coding.empty() && (coding.back() == ' ' || coding.back() == '\t'))
                coding.remove_suffix(1);
            if (!iequals(coding, "identity"))
                return refuse(
                    res, 415,
                    "a request body may not be compressed (Content-Encoding \"" +
                        it->second.substr(0, 40) + "\"); send it as it is");
        }
        return httplib::Server::HandlerResponse::Unhandled;
    }

    // The bearer token when the request sends one, else the session its cookie names.
    // A cookie is only ever a session id: the client token in a cookie opens nothing.
    Access presented_access(const httplib::Request& req) {
        const std::string authorization = req.get_header_value("Authorization");
        const std::string_view bearer = bearer_token(authorization);
        if (!bearer.empty()) return check_access(options.tokens, bearer, Role::Client);
        const std::string id =
            http_session::cookie_value(req.get_header_value("Cookie"), cookie_name);
        return !id.empty() && sessions.use(id) ? Access::Granted
                                               : Access::Unauthenticated;
    }

    // After the cross-site checks, so that a foreign page learns nothing more from a 401
    // than from a 403. Only the client token (or a session it opened) opens the API.
    httplib::Server::HandlerResponse token_check(const httplib::Request& req,
                                                 httplib::Response& res) {
        const Access access = presented_access(req);
        if (access == Access::Granted) {
            HttpFront::trust_current_request();
            return httplib::Server::HandlerResponse::Unhandled;
        }
        if (http_session::needs_token(req.method, req.path)) {
            res.set_header("Connection", "close");  // its body is never read
            send_refusal(res, access);
            return httplib::Server::HandlerResponse::Handled;
        }
        // Without the token, only a body the front has read whole (a sign-in): such a
        // request never holds a thread while its body trickles in.
        if (req.has_header("Transfer-Encoding"))
            return refuse(res, 411,
                          "a request without the client token must send Content-Length");
        if (req.get_header_value<uint64_t>("Content-Length") >
            options.front.max_small_body)
            return refuse(res, 413,
                          "a request without the client token may send at most " +
                              std::to_string(options.front.max_small_body) + " bytes");
        return httplib::Server::HandlerResponse::Unhandled;
    }

    // 401 with WWW-Authenticate (no or a wrong token) or 403 (the worker's), as JSON.
    static void send_refusal(httplib::Response& res, Access access) {
        if (access == Access::Unauthenticated)
            res.set_header("WWW-Authenticate", "Bearer");
        send_error(res, access == Access::Forbidden ? 403 : 401,
                   http_session::refusal_message(access));
    }

    void routes() {
        server.set_pre_routing_handler([this](const httplib::Request& req,
                                              httplib::Response& res) {
            // httplib answers several ranges with a multipart body it builds in memory,
            // overlapping ones too: 2,700 times "0-" (an 8 KB header, no token) made a
            // 293 MB answer of a 108 KB dashboard file. One range (a resumed download)
            // is served; for more, the whole, as HTTP allows. httplib parsed them into
            // its own Request, which it hands every handler as const only.
            if (req.ranges.size() > 1) {
                auto& whole = const_cast<httplib::Request&>(req);
                whole.ranges.clear();
                whole.headers.erase("Range");
            }
            for (auto check :
                 {&Impl::encoding_check, &Impl::cross_site_check, &Impl::token_check})
                if ((this->*check)(req, res) == httplib::Server::HandlerResponse::Handled)
                    return httplib::Server::HandlerResponse::Handled;
            return httplib::Server::HandlerResponse::Unhandled;
        });
        // A refusal's body was never read: what follows it on the connection is not a
        // request, so the connection ends with the response (httplib would read on).
        server.set_post_routing_handler(
            [](const httplib::Request&, httplib::Response& res) {
                if (res.get_header_value("Connection") == "close")
                    HttpFront::close_after_current_response();
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
                            throw ApiError(
                                404, "no render " + quoted_id(req.matches[1].str()));
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
                    throw ApiError(404, "no render " + quoted_id(req.matches[1].str()));
                send_json(res, render_detail(*info, progress_of(*info)));
            }));
        server.Delete(R"(/api/renders/([^/]+))",
                      guarded([this](const httplib::Request& req, auto& res) {
                          const std::string id = req.matches[1];
                          switch (coordinator.remove(id)) {
                              case Coordinator::Removal::Removed:
                                  thumbnails.forget(id);
                                  res.status = 204;
                                  return;
                              case Coordinator::Removal::Unknown:
                                  throw ApiError(404, "no render " + quoted_id(id));
                              case Coordinator::Removal::Unfinished:
                                  throw ApiError(409, "render " + quoted_id(id) +
                                                          " has not finished; cancel "
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
                if (!all) throw ApiError(404, "no render " + quoted_id(id));
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
        server.Get(
            R"(/api/renders/([^/]+)/events)",
            guarded([this](const httplib::Request& req, auto& res) {
                const std::string id = req.matches[1];
                const auto from = int64_t(
                    http_api::number_param("from", query(req, "from", "0"), 0, 1e15));
                const auto limit = size_t(
                    http_api::number_param("limit", query(req, "limit", "100"), 1, 1000));
                const auto page = coordinator.events(id, from - 1, limit);
                if (!page) throw ApiError(404, "no render " + quoted_id(id));
                json events = json::array();
                for (const RenderEvent& e : page->events) events.push_back(event_json(e));
                send_json(res, {{"id", id},
                                {"events", events},
                                {"omitted", page->omitted},
                                {"next", page->events.empty()
                                             ? json(from)
                                             : json(page->events.back().seq + 1)}});
            }));
    }

    // The dashboard's sign-in: the client token opens a session, whose random id the
    // cookie carries (docs/API.md, "Authentication"). GET needs the token like every
    // route; POST and DELETE do not.
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
                                   http_session::sign_in_cookie(cookie_name,
                                                                sessions.open(), https));
                    send_json(res, {{"ok", true}});
                    return;
                }
                send_refusal(res, access);
            }));
        // Ends the session the cookie names, so that a copy of the cookie opens nothing
        // either; knowing the id is what signing out needs.
        server.Delete(
            "/api/session", [this](const httplib::Request& req, httplib::Response& res) {
                const std::string id = http_session::cookie_value(
                    req.get_header_value("Cookie"), cookie_name);
                if (!id.empty()) sessions.close(id);
                res.set_header("Set-Cookie",
                               http_session::sign_out_cookie(cookie_name, https));
                send_json(res, {{"ok", true}});
            });
    }

    // What the dashboard draws of one render: preview, heat maps, buckets. Every route
    // that makes or sends an image takes a place among image_requests first.
    void image_routes() {
        server.Get(R"(/api/renders/([^/]+)/preview\.png)",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const std::string id = req.matches[1];
                       const double exposure = http_api::number_param(
                           "exposure", query(req, "exposure", "0"), -20, 20);
                       const auto size = uint32_t(http_api::number_param(
                           "size", query(req, "size", "1024"), 16, 8192));
                       render_or_404(id);
                       Admission::Place place = admit_image(req, res);
                       std::string png =
                           http_api::preview_png(image_or_404(id, false), exposure, size);
                       res.set_header("Cache-Control", "no-store");
                       send_image(res, std::move(png), "image/png", std::move(place));
                   }));
        server.Get(R"(/api/renders/([^/]+)/thumbnail\.png)",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const std::string id = req.matches[1];
                       const RenderInfo info = render_or_404(id);
                       // Whatever changes the image changes one of these.
                       const std::string version = std::to_string(info.created_ms) + "/" +
                                                   std::to_string(info.samples_done) +
                                                   "/" +
                                                   std::to_string(info.rounds_done) +
                                                   "/" + std::to_string(int(info.state));
                       // Only a thumbnail made anew takes a place: a kept one is a copy
                       // of a few KB.
                       const std::string png = thumbnails.get(id, version, [&] {
                           const Admission::Place place = admit_image(req, res);
                           return thumbnail_png(id);
                       });
                       res.set_header("Cache-Control", "no-store");
                       res.set_content(png, "image/png");
                   }));
        server.Get(R"(/api/renders/([^/]+)/image\.exr)",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const std::string id = req.matches[1];
                       const std::string aovs = query(req, "aovs", "0");
                       if (aovs != "0" && aovs != "1")
                           throw ApiError(400, "'aovs' must be 0 or 1, got \"" +
                                                   aovs.substr(0, 8) + "\"");
                       render_or_404(id);
                       Admission::Place place = admit_image(req, res);
                       res.set_header("Cache-Control", "no-store");
                       res.set_header("Content-Disposition",
                                      "attachment; filename=\"" + id + ".exr\"");
                       if (const auto file = coordinator.image_file(id)) {
                           // A finished render's stored file as it is, as FetchImage
                           // sends it, read as it is sent: the response holds a chunk,
                           // not the file.
                           send_file(res, stored_image(*file, aovs == "1"), "image/x-exr",
                                     std::move(place));
                           return;
                       }
                       std::string exr = encode_exr(image_or_404(id, aovs == "1"));
                       // OpenEXR's own name for its type; not compressed again (ZIP
                       // inside).
                       send_image(res, std::move(exr), "image/x-exr", std::move(place));
                   }));
        server.Get(
            R"(/api/renders/([^/]+)/maps)",
            guarded([this](const httplib::Request& req, auto& res) {
                const std::string id = req.matches[1];
                const std::string kind = query(req, "kind", "spp");
                if (kind != "spp" && kind != "error")
                    throw ApiError(400,
                                   "'kind' must be spp or error, got \"" + kind + "\"");
                const auto size = uint32_t(
                    http_api::number_param("size", query(req, "size", "256"), 8, 256));
                render_or_404(id);
                Admission::Place place = admit_image(req, res);
                const auto map_kind =
                    kind == "spp" ? http_api::MapKind::Spp : http_api::MapKind::Error;
                json map = http_api::pixel_map(image_or_404(id, true), map_kind, size);
                map["id"] = id;
                res.set_header("Cache-Control", "no-store");
                send_image(res, json_text(map), "application/json", std::move(place));
            }));
        server.Get(R"(/api/renders/([^/]+)/buckets)",
                   guarded([this](const httplib::Request& req, auto& res) {
                       const std::string id = req.matches[1];
                       const RenderInfo info = render_or_404(id);
                       const auto buckets = coordinator.buckets(id);
                       if (!buckets) throw ApiError(404, "no render " + quoted_id(id));
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
        // Every method with its parameters: keys, defaults, bounds, help (the dashboard's
        // form is built from it; strategy_parameters.h is the one table).
        server.Get("/api/methods", guarded([](const httplib::Request&, auto& res) {
                       send_json(res, {{"methods", methods_json()}});
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
        const size_t threads = options.front.threads;
        if (threads < kFreeThreads || options.max_event_streams + kFreeThreads > threads)
            throw std::invalid_argument(
                "http: at most " +
                std::to_string(threads - std::min(threads, kFreeThreads)) +
                " event streams, so that the server keeps threads for other requests");
        server.new_task_queue = [] { return new HandToFront; };
        server.set_payload_max_length(1 << 20);
        // What the Keep-Alive header tells clients; the front enforces both.
        server.set_keep_alive_max_count(options.front.requests_per_connection);
        server.set_keep_alive_timeout(
            std::max<time_t>(1, std::chrono::duration_cast<std::chrono::seconds>(
                                    options.front.request_deadline)
                                    .count()));
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
        made.requests->deepen_backlog();
        hosts.emplace(host, port, options.allowed_hosts);
        cookie_name = http_session::cookie_name(port, https);
        front = std::make_unique<HttpFront>(
            options.front, made.tls,
            [this](FrontConnection& c, bool close, bool& closed) {
                return made.requests->serve(c, close, closed);
            });
        made.requests->front = front.get();
        snapshot(false);  // later updates say what changed since now
        seen_storage_warning = coordinator.storage_warning();
        listener = std::thread([this] { server.listen_after_bind(); });
        // httplib's stop() does nothing until its listener has begun (is_running): a
        // server stopped at once would leave that thread in accept() for ever, and stop()
        // waiting for it. Bounded, should the listener end at once.
        for (int i = 0; i < 5000 && !server.is_running(); ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        broadcaster = std::thread([this] { broadcast(); });
    }

    void stop() {
        std::call_once(stopped, [this] {
            hub.stop();
            server.stop();
            if (listener.joinable()) listener.join();
            if (front) front->stop();
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
