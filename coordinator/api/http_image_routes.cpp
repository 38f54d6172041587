// What the dashboard draws of a render and what it downloads: preview, thumbnail, EXR,
// heat maps, buckets, each image taking a place among image_requests first
// (docs/SECURITY.md, "HTTP image routes"); a group of HttpServer's routes
// (http_server_impl.h).
#include "http_server_impl.h"

#include "exr_io.h"
#include "stored_image.h"

namespace aliquot {

using http_api::ApiError;
using nlohmann::json;

Image HttpServer::Impl::image_or_404(const std::string& id, bool aovs) {
    std::optional<Image> image = coordinator.image(id, aovs);
    if (!image) throw ApiError(404, "render " + quoted_id(id) + " has no image yet");
    return std::move(*image);
}

// A render in memory's thumbnail is made straight from its sums; a stored one's from
// its EXR, once (a finished render's version does not change).
std::string HttpServer::Impl::thumbnail_png(const std::string& id) {
    std::string png;
    if (coordinator.read_sums(id, [&](const Accumulator& sums) {
            png = http_api::thumbnail_png(sums, kThumbnailSide);
        }))
        return png;
    return http_api::preview_png(image_or_404(id, false), 0, kThumbnailSide);
}

// A place among image_requests, or ApiError 503 with Retry-After.
Admission::Place HttpServer::Impl::admit_image(const httplib::Request& req,
                                               httplib::Response& res) {
    Admission::Ticket ticket = image_requests.take(req.remote_addr);
    if (!ticket.place) {
        res.set_header("Retry-After", "2");
        throw ApiError(503,
                       ticket.peer_share_full
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

// What the dashboard draws of one render: preview, heat maps, buckets. Every route
// that makes or sends an image takes a place among image_requests first.
void HttpServer::Impl::image_routes() {
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
                                               std::to_string(info.samples_done) + "/" +
                                               std::to_string(info.rounds_done) + "/" +
                                               std::to_string(int(info.state));
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
    server.Get(R"(/api/renders/([^/]+)/maps)",
               guarded([this](const httplib::Request& req, auto& res) {
                   const std::string id = req.matches[1];
                   const std::string kind = query(req, "kind", "spp");
                   if (kind != "spp" && kind != "error")
                       throw ApiError(
                           400, "'kind' must be spp or error, got \"" + kind + "\"");
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

}  // namespace aliquot
