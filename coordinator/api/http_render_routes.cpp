// The HTTP API's renders: list, submit, read, cancel, change priority, delete, rounds,
// events (docs/API.md); a group of HttpServer's routes (http_server_impl.h).
#include "http_server_impl.h"

#include <algorithm>

#include "unix_millis.h"

namespace aliquot {

using http_api::ApiError;
using nlohmann::json;

std::optional<BucketProgress> HttpServer::Impl::progress_of(const RenderInfo& info) {
    // Only running renders: a finished one reports progress 1 and may live only in
    // the store, where its buckets cost a read of every round.
    if (is_terminal(info.state)) return std::nullopt;
    if (info.method != "dammertz") return std::nullopt;
    const auto b = coordinator.buckets(info.id);
    if (!b || b->empty()) return std::nullopt;
    return bucket_progress(*b, info.width, info.height);
}

RenderInfo HttpServer::Impl::render_or_404(const std::string& id) {
    // No id the coordinator issues is longer: a longer one is not looked up.
    if (id.size() > 64) throw ApiError(404, "no render " + quoted_id(id));
    std::optional<RenderInfo> info = coordinator.info(id);
    if (!info) throw ApiError(404, "no render " + quoted_id(id));
    return *info;
}

json HttpServer::Impl::list_renders(size_t limit) {
    json out = json::array();
    for (const RenderInfo& info : coordinator.list(limit))
        out.push_back(render_summary(info, progress_of(info)));
    return out;
}

// Renders: list, submit, read, cancel, change priority, delete, rounds.
void HttpServer::Impl::render_routes() {
    server.Get("/api/renders", guarded([this](const httplib::Request& req, auto& res) {
                   const size_t limit = size_t(http_api::number_param(
                       "limit", query(req, "limit", "200"), 1, double(options.max_list)));
                   send_json(res, {{"renders", list_renders(limit)},
                                   {"now_ms", unix_millis_now()},
                                   {"storage_warning", coordinator.storage_warning()}});
               }));
    server.Post("/api/renders", guarded([this](const httplib::Request& req, auto& res) {
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
                                       "no render " + quoted_id(req.matches[1].str()));
                    send_json(res, render_detail(*info));
                }));
    server.Patch(R"(/api/renders/([^/]+))",
                 guarded([this](const httplib::Request& req, auto& res) {
                     const int32_t priority = http_api::parse_priority_request(req.body);
                     std::optional<RenderInfo> info;
                     try {
                         info = coordinator.set_priority(req.matches[1], priority);
                     } catch (const RenderFinished& e) {
                         throw ApiError(409, e.what());
                     }
                     if (!info)
                         throw ApiError(404,
                                        "no render " + quoted_id(req.matches[1].str()));
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
            const auto limit = size_t(
                http_api::number_param("limit", query(req, "limit", "1000"), 1, 1000));
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
    server.Get(R"(/api/renders/([^/]+)/events)",
               guarded([this](const httplib::Request& req, auto& res) {
                   const std::string id = req.matches[1];
                   const auto from = int64_t(
                       http_api::number_param("from", query(req, "from", "0"), 0, 1e15));
                   const auto limit = size_t(http_api::number_param(
                       "limit", query(req, "limit", "100"), 1, 1000));
                   const auto page = coordinator.events(id, from - 1, limit);
                   if (!page) throw ApiError(404, "no render " + quoted_id(id));
                   json events = json::array();
                   for (const RenderEvent& e : page->events)
                       events.push_back(event_json(e));
                   send_json(res, {{"id", id},
                                   {"events", events},
                                   {"omitted", page->omitted},
                                   {"next", page->events.empty()
                                                ? json(from)
                                                : json(page->events.back().seq + 1)}});
               }));
}

}  // namespace aliquot
