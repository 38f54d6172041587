// A render id as the API's error messages show it. The id is the caller's own text (a
// URL path, a gRPC field of up to 4 MiB): a message must not send a megabyte back, nor
// bytes that end a log line or a terminal's sanity.
#pragma once

#include <string>
#include <string_view>

namespace aliquot {

// The id itself when it is at most 64 bytes of printable ASCII (every id the coordinator
// issues); else its first 64 bytes, each one that is not printable ASCII as '?', then
// "... (N bytes)".
std::string shown_id(std::string_view id);

}  // namespace aliquot
