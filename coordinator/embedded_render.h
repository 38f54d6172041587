// The embedded render: an in-memory Coordinator and local worker threads speaking the
// same lease protocol by direct calls, no sockets. Same rounds, same jobs, same bytes as
// a farm.
#pragma once

#include <functional>

#include "coordinator.h"

namespace aliquot {

struct EmbeddedResult {
    RenderInfo info;
    Image image;
};

// Renders `spec` with `threads` local workers; `progress` is called from this thread a
// few times a second and once at the end. Throws what Coordinator::submit throws.
EmbeddedResult render_embedded(
    const RenderSpec& spec, int threads, bool aovs,
    const std::function<void(const RenderInfo&)>& progress = {});

}  // namespace aliquot
