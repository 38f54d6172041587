// The HTTP API's farm apart from its renders: health, metrics, workers, scenes and
// methods (docs/API.md); a group of HttpServer's routes (http_server_impl.h).
#include "http_server_impl.h"

#include "strategy_parameters.h"
#include "unix_millis.h"

namespace aliquot {

using nlohmann::json;

json HttpServer::Impl::workers_json() {
    json out = json::array();
    for (const WorkerStatus& w : coordinator.workers())
        out.push_back(http_api::worker_json(w));
    return out;
}

// Health, metrics, workers, scenes, methods.
void HttpServer::Impl::farm_routes() {
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
    server.Get(
        "/api/workers", guarded([this](const httplib::Request&, auto& res) {
            send_json(res, {{"workers", workers_json()}, {"now_ms", unix_millis_now()}});
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
}

}  // namespace aliquot
