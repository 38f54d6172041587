// RenderState: where a render is in its life, and its one spelling table: the store, the
// JSON of the HTTP API and the CLI all write "running" etc. through to_string. gRPC
// carries v1::RenderState instead, mapped in coordinator/api/render_proto.h. It lives in
// the lifecycle room, below the store that records it and the rooms that read it, so the
// api, the study and the CLI name a state without seeing the store, and nothing below the
// api room sees protobuf.
#pragma once

#include <optional>
#include <string_view>

namespace aliquot {

enum class RenderState { Queued, Running, Done, Cancelled, Failed };

// "queued", "running", "done", "cancelled", "failed".
std::string_view to_string(RenderState state);
std::optional<RenderState> parse_render_state(std::string_view text);
// Done, Cancelled and Failed: the render will not run again.
bool is_terminal(RenderState state);

}  // namespace aliquot
