// What the study's loop needs from wherever its renders run (the embedded coordinator, a
// farm): submit one, follow it, collect it. Declared here, by its user; cli/ has the
// farm's.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "image.h"
#include "render_spec.h"
#include "render_state.h"

namespace aliquot {

class RunStore;

struct StudyRenderStatus {
    bool known = false;  // false: the backend has no such render (any more)
    RenderState state = RenderState::Queued;
    std::string error;
    uint64_t done = 0, planned = 0;
};

// A finished render as the study records it.
struct CollectedRender {
    std::string local_id;  // the render's record in the study's database
    uint64_t samples = 0, rays = 0;
    double seconds = 0;
    std::string outcome_json;
    Image image;  // with the spp channel
};

class StudyBackend {
public:
    virtual ~StudyBackend() = default;
    // Recorded with each submitted render: only the backend that runs it follows it.
    virtual std::string origin() const = 0;
    // Renders side by side (a farm), or one at a time so each wall time is the render's
    // own.
    virtual bool parallel() const = 0;
    virtual std::string submit(const RenderSpec& spec,
                               const std::filesystem::path& reference_path) = 0;
    virtual StudyRenderStatus status(const std::string& id) = 0;
    // A done render. `store` is the study's database: a backend whose renders are
    // recorded elsewhere mirrors them there, so one database holds the whole study.
    virtual CollectedRender collect(const std::string& id, const RenderSpec& spec,
                                    RunStore& store) = 0;
    virtual void cancel(const std::string& id) = 0;
    // Renders not yet finished that this backend knows of (embedded: resumed ones).
    virtual std::vector<std::string> unfinished() { return {}; }
    // Until something may have changed.
    virtual void wait() = 0;
};

}  // namespace aliquot
