#include "render_attributes.h"

#include <nlohmann/json.hpp>

namespace aliquot {

std::map<std::string, std::string> render_attributes(const RenderSpec& spec,
                                                     const std::string& scene_hash,
                                                     uint64_t samples_planned,
                                                     uint64_t samples_merged) {
    return {{"aliquot:sceneHash", scene_hash},
            {"aliquot:method", spec.strategy.method},
            // nlohmann's objects keep their keys sorted: one spelling per strategy.
            {"aliquot:strategy", nlohmann::json(spec.strategy).dump()},
            {"aliquot:seed", std::to_string(spec.seed)},
            {"aliquot:budget", std::to_string(samples_planned)},
            {"aliquot:samples", std::to_string(samples_merged)}};
}

}  // namespace aliquot
