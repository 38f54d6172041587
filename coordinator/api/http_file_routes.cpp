// Files the HTTP server reads from disk: the study reports (`aliquot study`) and the
// built dashboard; a group of HttpServer's routes (http_server_impl.h).
#include "http_server_impl.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace aliquot {

using http_api::ApiError;
using nlohmann::json;

namespace {

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

}  // namespace

json HttpServer::Impl::list_studies() {
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
                 it != fs::recursive_directory_iterator() && names.size() < 200; ++it) {
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

void HttpServer::Impl::study_file(const std::string& label, const std::string& name,
                                  const std::string& rel, httplib::Response& res) {
    namespace fs = std::filesystem;
    const auto source = std::find_if(options.study_dirs.begin(), options.study_dirs.end(),
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

void HttpServer::Impl::study_routes() {
    server.Get("/api/studies", guarded([this](const httplib::Request&, auto& res) {
                   send_json(res, {{"studies", list_studies()}});
               }));
    server.Get(R"(/api/studies/([^/]+)/([^/]+)/(.+))",
               guarded([this](const httplib::Request& req, auto& res) {
                   study_file(req.matches[1], req.matches[2], req.matches[3], res);
               }));
}

// The built dashboard, or a page saying how to build it.
void HttpServer::Impl::dashboard_route() {
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

}  // namespace aliquot
