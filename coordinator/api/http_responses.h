// How the HTTP server's routes answer: JSON (never a throw from bytes that are not
// UTF-8), JSON errors, and the bodies of the image routes, sent while they hold their
// place. Shared by the files of the routes (http_server_impl.h).
#pragma once

#include <httplib.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "admission.h"

namespace aliquot {

// Every JSON this server sends: bytes that are not UTF-8 (a URL's %FF echoed in an error,
// a string cut mid-character) become U+FFFD instead of a throw from dump(), which outside
// a handler's try would end the process.
std::string json_text(const nlohmann::json& body);

void send_json(httplib::Response& res, const nlohmann::json& body, int status = 200);

// A name of the request (a render id, a study's path) as an error message quotes it:
// bounded, printable.
std::string quoted_id(const std::string& id);

void send_error(httplib::Response& res, int status, const std::string& message);

// Sends `body`, made by an image route, keeping `place` until it is sent or cut: the
// body is what the place bounds, and a slow reader holds both until the pace it must
// keep (FrontLimits::min_read_rate) cuts it.
void send_image(httplib::Response& res, std::string body, const std::string& type,
                Admission::Place place);

// Sends the file at `path` as it is read, 1 MiB at a time: the response holds one chunk,
// never the file, and keeps `place` until it is sent or cut, its reader paced as
// send_image's. The file is opened here (a missing one is ApiError 404); one renamed or
// deleted meanwhile is still read whole.
void send_file(httplib::Response& res, const std::filesystem::path& path,
               const std::string& type, Admission::Place place);

}  // namespace aliquot
