#include "render_proto.h"

namespace aliquot {

v1::RenderState to_proto(RenderState state) {
    switch (state) {
        case RenderState::Queued:
            return v1::RENDER_STATE_QUEUED;
        case RenderState::Running:
            return v1::RENDER_STATE_RUNNING;
        case RenderState::Done:
            return v1::RENDER_STATE_DONE;
        case RenderState::Cancelled:
            return v1::RENDER_STATE_CANCELLED;
        case RenderState::Failed:
            return v1::RENDER_STATE_FAILED;
    }
    return v1::RENDER_STATE_UNSPECIFIED;
}

RenderState from_proto(v1::RenderState state) {
    switch (state) {
        case v1::RENDER_STATE_QUEUED:
            return RenderState::Queued;
        case v1::RENDER_STATE_RUNNING:
            return RenderState::Running;
        case v1::RENDER_STATE_DONE:
            return RenderState::Done;
        case v1::RENDER_STATE_CANCELLED:
            return RenderState::Cancelled;
        case v1::RENDER_STATE_FAILED:
            return RenderState::Failed;
        default:
            break;
    }
    throw WireError("render state " + std::to_string(int(state)) +
                    " is not one this build knows");
}

void to_proto(const RenderInfo& i, v1::RenderInfo& out) {
    out.set_id(i.id);
    out.set_scene(i.scene_name);
    out.set_width(i.width);
    out.set_height(i.height);
    out.set_seed(i.seed);
    out.set_method(i.method);
    out.set_strategy_json(i.strategy_json);
    out.set_state(to_proto(i.state));
    out.set_error(i.error);
    out.set_samples_done(i.samples_done);
    out.set_samples_planned(i.samples_planned);
    out.set_rounds(i.rounds_done);
    out.set_seconds(i.seconds);
    out.set_samples_per_second(i.samples_per_second);
    out.set_error_estimate(i.error_estimate);
    out.set_error_vs_reference(i.error_vs_reference);
    out.set_created_ms(i.created_ms);
    out.set_finished_ms(i.finished_ms);
    out.set_outcome_json(i.outcome_json);
    out.set_rays(i.rays);
    out.set_priority(i.priority);
    out.set_name(i.name);
    out.set_queue_position(i.queue_position);
    if (i.mean_bias) out.set_mean_bias(*i.mean_bias);
    if (i.mean_bias_se) out.set_mean_bias_se(*i.mean_bias_se);
}

RenderInfo from_proto(const v1::RenderInfo& in) {
    RenderInfo i;
    i.id = in.id();
    i.scene_name = in.scene();
    i.width = in.width();
    i.height = in.height();
    i.seed = in.seed();
    i.method = in.method();
    i.strategy_json = in.strategy_json();
    i.state = from_proto(in.state());
    i.priority = in.priority();
    i.error = in.error();
    i.samples_done = in.samples_done();
    i.samples_planned = in.samples_planned();
    i.rounds_done = in.rounds();
    i.seconds = in.seconds();
    i.samples_per_second = in.samples_per_second();
    i.error_estimate = in.error_estimate();
    i.error_vs_reference = in.error_vs_reference();
    i.created_ms = in.created_ms();
    i.finished_ms = in.finished_ms();
    i.outcome_json = in.outcome_json();
    i.rays = in.rays();
    i.name = in.name();
    i.queue_position = in.queue_position();
    if (in.has_mean_bias()) i.mean_bias = in.mean_bias();
    if (in.has_mean_bias_se()) i.mean_bias_se = in.mean_bias_se();
    return i;
}

void to_proto(const WorkerStatus& w, v1::WorkerInfo& out) {
    out.set_name(w.name);
    out.set_threads(w.threads);
    out.set_state(w.state);
    for (const std::string& l : w.leases) out.add_leases(l);
    out.set_samples_traced(w.samples_traced);
    out.set_samples_per_second(w.samples_per_second);
    out.set_last_seen_ms(w.last_seen_ms);
    out.set_host(w.host);
    out.set_version(w.version);
    out.set_failures(w.failures);
}

void to_proto(const RenderEvent& e, v1::RenderEvent& out) {
    out.set_seq(e.seq);
    out.set_at_ms(e.at_ms);
    out.set_kind(std::string(to_string(e.kind)));
    out.set_fields_json(fields_json(e.fields));
}

WorkerStatus from_proto(const v1::WorkerInfo& in) {
    WorkerStatus w;
    w.name = in.name();
    w.threads = in.threads();
    w.state = in.state();
    w.leases.assign(in.leases().begin(), in.leases().end());
    w.samples_traced = in.samples_traced();
    w.samples_per_second = in.samples_per_second();
    w.last_seen_ms = in.last_seen_ms();
    w.host = in.host();
    w.version = in.version();
    w.failures = in.failures();
    return w;
}

}  // namespace aliquot
