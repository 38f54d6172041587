#include "render_info.h"

#include <nlohmann/json.hpp>

#include "render_session.h"

namespace aliquot {

RenderInfo info_of(const RenderSession& s, int32_t priority) {
    RenderInfo info;
    info.priority = priority;
    info.id = s.id();
    info.scene_name = s.spec().scene_name;
    info.name = s.spec().name;
    info.width = s.spec().width;
    info.height = s.spec().height;
    info.seed = s.spec().seed;
    info.method = s.spec().strategy.method;
    info.strategy_json = nlohmann::json(s.spec().strategy).dump();
    info.state = s.state();
    info.error = s.error();
    info.samples_done = s.merged().total_samples();
    info.samples_planned = s.samples_planned();
    info.rays = s.merged().total_rays();
    info.rounds_done = s.rounds_done();
    info.seconds = s.seconds();
    info.samples_per_second =
        info.seconds > 0 ? double(info.samples_done) / info.seconds : 0;
    info.error_estimate = s.error_estimate();
    info.error_vs_reference = s.error_vs_reference();
    info.mean_bias = s.last_round().mean_bias;
    info.mean_bias_se = s.last_round().mean_bias_se;
    info.created_ms = s.created_ms();
    info.outcome_json = s.strategy().outcome().dump();
    return info;
}

}  // namespace aliquot
