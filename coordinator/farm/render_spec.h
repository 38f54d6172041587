// RenderSpec: everything that defines a render's output bytes (scene, size, seed,
// method), plus an optional reference image that errors are measured against.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "image.h"
#include "strategy_params.h"

namespace aliquot {

struct RenderSpec {
    std::string scene_name;  // for people: built-in name or file
    std::string scene_json;  // self-contained (meshes inlined)
    uint32_t width = 0, height = 0;
    uint64_t seed = 0;
    StrategyParams strategy;
    std::optional<Image> reference;
    // Scheduling, not output: leases go to the highest priority first, in submission
    // order within one; changeable while the render runs (Coordinator::set_priority).
    int32_t priority = 0;
    // For people (`submit --name`): at most kMaxRenderName bytes of UTF-8, no control
    // characters; may be empty.
    std::string name;
    // Output, opt-in: workers also return each sample's first-hit albedo and normal, kept
    // beside the colour (AuxSums) for a denoiser and written as EXR layers (issue 34).
    // Off, a render's jobs, results and buffers are what they were.
    bool aux = false;
};

constexpr size_t kMaxRenderName = 200;
// Why `name` cannot name a render, or "" when it can.
std::string render_name_error(const std::string& name);

// A 128-bit content address (32 hex digits) of any bytes; not cryptographic.
std::string content_hash(const std::string& bytes);
// The content address of a scene's self-contained JSON: scenes are stored and cached by
// it.
inline std::string scene_hash(const std::string& scene_json) {
    return content_hash(scene_json);
}

// Throws std::invalid_argument naming what is wrong: a name too long or with control
// characters, resolution 0 or above `max_side`,
// strategy parameters, a reference of another resolution.
void validate(const RenderSpec& spec, uint32_t max_side = 8192);

}  // namespace aliquot
