// What a render's EXR says about how it was made, as string attributes a tool shows
// (`oiiotool --info -v`, tev, Blender): enough to make the same bytes again. Only what
// fixes the pixels goes in (no scene name, date or host), so the same spec and seed still
// give the same file.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "render_spec.h"

namespace aliquot {

// "aliquot:sceneHash", "aliquot:method", "aliquot:strategy" (every parameter, as JSON),
// "aliquot:seed" (decimal), "aliquot:budget" (samples the strategy plans, a cap for
// methods that stop early) and "aliquot:samples" (samples merged into the image).
std::map<std::string, std::string> render_attributes(const RenderSpec& spec,
                                                     const std::string& scene_hash,
                                                     uint64_t samples_planned,
                                                     uint64_t samples_merged);

}  // namespace aliquot
