// HttpServer's state, shared by the files that define its routes, a group a file:
// http_render_routes.cpp (renders and their control), http_access.cpp (the checks before
// every route, and the dashboard's sign-in), http_image_routes.cpp (previews, thumbnails,
// maps, EXR downloads), http_farm_routes.cpp (health, metrics, workers, scenes, methods),
// http_live_updates.cpp (the event streams and what they send), http_file_routes.cpp
// (study reports, the dashboard's files); http_server.cpp starts and stops it all.
// Internal to the api room: http_server.h is the interface.
#pragma once

#include <httplib.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "admission.h"
#include "browser_sessions.h"
#include "event_hub.h"
#include "farm_log.h"
#include "http_api.h"
#include "http_fronted_server.h"
#include "http_responses.h"
#include "http_server.h"
#include "render_state.h"
#include "scene_loader.h"
#include "thumbnail_cache.h"

namespace aliquot {

// A query parameter of the request, or `fallback` when it has none.
inline std::string query(const httplib::Request& req, const std::string& name,
                         const std::string& fallback) {
    return req.has_param(name.c_str()) ? req.get_param_value(name.c_str()) : fallback;
}

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

    // Tells the browsers when writing the run record starts or stops failing.
    std::string seen_storage_warning;

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

    Impl(Coordinator& c, HttpOptions o);

    // ---- renders (http_render_routes.cpp) ----
    std::optional<BucketProgress> progress_of(const RenderInfo& info);
    RenderInfo render_or_404(const std::string& id);
    nlohmann::json list_renders(size_t limit);
    void render_routes();

    // ---- the farm (http_farm_routes.cpp) ----
    nlohmann::json workers_json();
    void farm_routes();

    // ---- live updates (http_live_updates.cpp) ----
    void snapshot(bool publish);
    void publish_storage_warning();
    void broadcast();
    void events(const httplib::Request& req, httplib::Response& res);
    void event_routes();

    // ---- images (http_image_routes.cpp) ----
    Image image_or_404(const std::string& id, bool aovs);
    std::string thumbnail_png(const std::string& id);
    Admission::Place admit_image(const httplib::Request& req, httplib::Response& res);
    void image_routes();

    // ---- files (http_file_routes.cpp) ----
    nlohmann::json list_studies();
    void study_file(const std::string& label, const std::string& name,
                    const std::string& rel, httplib::Response& res);
    void study_routes();
    void dashboard_route();

    // ---- who may (http_access.cpp) ----
    httplib::Server::HandlerResponse refuse(httplib::Response& res, int status,
                                            const std::string& message);
    httplib::Server::HandlerResponse cross_site_check(const httplib::Request& req,
                                                      httplib::Response& res);
    httplib::Server::HandlerResponse encoding_check(const httplib::Request& req,
                                                    httplib::Response& res);
    Access presented_access(const httplib::Request& req);
    httplib::Server::HandlerResponse token_check(const httplib::Request& req,
                                                 httplib::Response& res);
    static void send_refusal(httplib::Response& res, Access access);
    void session_routes();

    // ---- routing: guarded here, the rest in http_server.cpp ----

    // Runs a handler; every refusal becomes a JSON error with a 4xx status.
    template <typename Fn>
    httplib::Server::Handler guarded(Fn fn) {
        return [fn](const httplib::Request& req, httplib::Response& res) {
            try {
                fn(req, res);
            } catch (const http_api::ApiError& e) {
                send_error(res, e.status(), e.what());
            } catch (const MemoryBudgetError& e) {  // submit: try again later
                send_error(res, 429, e.what());
            } catch (const std::invalid_argument& e) {  // spec validation
                send_error(res, 400, e.what());
            } catch (const SceneError& e) {
                send_error(res, 400, e.what());
            } catch (const nlohmann::json::exception& e) {
                send_error(res, 400, std::string("malformed request: ") + e.what());
            } catch (const std::exception& e) {
                log_farm_error(req.method + " " + req.path + ": " + e.what(),
                               "http_error");
                send_error(res, 500, std::string("internal error: ") + e.what());
            }
        };
    }

    void routes();
    void error_routes();
    void start(const std::string& address);
    void stop();
};

}  // namespace aliquot
