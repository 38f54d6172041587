#include "render_state.h"

namespace aliquot {

std::string_view to_string(RenderState state) {
    switch (state) {
        case RenderState::Queued:
            return "queued";
        case RenderState::Running:
            return "running";
        case RenderState::Done:
            return "done";
        case RenderState::Cancelled:
            return "cancelled";
        case RenderState::Failed:
            return "failed";
    }
    return "failed";
}

std::optional<RenderState> parse_render_state(std::string_view text) {
    for (RenderState s : {RenderState::Queued, RenderState::Running, RenderState::Done,
                          RenderState::Cancelled, RenderState::Failed})
        if (text == to_string(s)) return s;
    return std::nullopt;
}

bool is_terminal(RenderState state) {
    return state == RenderState::Done || state == RenderState::Cancelled ||
           state == RenderState::Failed;
}

}  // namespace aliquot
