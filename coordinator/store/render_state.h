// RenderState: where a render is in its life, and its spelling in the store and the API.
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
