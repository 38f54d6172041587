#include "metrics.h"

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/metric_family.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>

#include <vector>

namespace aliquot {

namespace {

using prometheus::ClientMetric;
using prometheus::MetricFamily;
using prometheus::MetricType;

// A Lease long-polls for up to 30 s, so its buckets reach that far; a merge is
// microseconds for a small job and up to seconds when it ends a round of a large render.
const prometheus::Histogram::BucketBoundaries kLeaseBuckets = {
    0.001, 0.005, 0.01, 0.05, 0.1, 0.25, 0.5, 1, 2, 5, 10, 30};
const prometheus::Histogram::BucketBoundaries kMergeBuckets = {
    0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025,
    0.05,   0.1,     0.25,   0.5,   1,      2.5,   5};

MetricFamily family(std::string name, std::string help, MetricType type) {
    return {std::move(name), std::move(help), type, {}};
}

void add(MetricFamily& f, double value, std::vector<ClientMetric::Label> labels = {}) {
    ClientMetric m;
    m.label = std::move(labels);
    if (f.type == MetricType::Counter)
        m.counter.value = value;
    else
        m.gauge.value = value;
    f.metric.push_back(std::move(m));
}

// A family of one unlabelled value: most of the farm's figures are one number each.
void add_single(std::vector<MetricFamily>& out, std::string name, std::string help,
                MetricType type, double value) {
    MetricFamily f = family(std::move(name), std::move(help), type);
    add(f, value);
    out.push_back(std::move(f));
}

// The farm as it is now, read from the Coordinator's public accessors.
std::vector<MetricFamily> farm_state(Coordinator& c) {
    std::vector<MetricFamily> out;

    MetricFamily renders =
        family("aliquot_renders",
               "Renders by state, as the run record has them (in memory without one).",
               MetricType::Gauge);
    const std::map<RenderState, uint64_t> counts = c.render_counts();
    for (RenderState s : {RenderState::Queued, RenderState::Running, RenderState::Done,
                          RenderState::Cancelled, RenderState::Failed}) {
        const auto it = counts.find(s);
        add(renders, it == counts.end() ? 0 : double(it->second),
            {{"state", std::string(to_string(s))}});
    }
    out.push_back(std::move(renders));

    add_single(out, "aliquot_samples_merged_total",
               "Samples merged into renders since the coordinator started.",
               MetricType::Counter, double(c.samples_merged()));

    // A round end holds up the render's workers unless its next round was opened ahead
    // (render_session.h), so the wait against the render time says how much of it the
    // coordinator costs: the share issue 14 bounds (bench/round_end_share.sh).
    add_single(out, "aliquot_rounds_ended_total",
               "Rounds ended across renders since the coordinator started.",
               MetricType::Counter, double(c.rounds_ended()));
    add_single(
        out, "aliquot_round_end_seconds_total",
        "Wall seconds of the calls that ended a round (the last merge, the record, "
        "planning and cutting the next round), while none of the render's jobs "
        "was out.",
        MetricType::Counter, c.round_end_seconds());
    add_single(out, "aliquot_round_end_cpu_seconds_total",
               "CPU seconds of those calls, the band pool's threads included.",
               MetricType::Counter, c.round_end_cpu_seconds());
    add_single(out, "aliquot_round_end_wait_seconds_total",
               "Wall seconds of those calls after which the render's next round had not "
               "been opened ahead: its workers waited through them.",
               MetricType::Counter, c.round_end_wait_seconds());

    // The states are WorkerStatus's three; a state outside them is not reported rather
    // than becoming a new label value.
    std::map<std::string, uint64_t> by_state = {{"idle", 0}, {"busy", 0}, {"lost", 0}};
    for (const WorkerStatus& w : c.workers()) {
        const auto it = by_state.find(w.state);
        if (it != by_state.end()) ++it->second;
    }
    MetricFamily workers =
        family("aliquot_workers", "Workers the coordinator remembers, by state.",
               MetricType::Gauge);
    for (const auto& [state, n] : by_state) add(workers, double(n), {{"state", state}});
    out.push_back(std::move(workers));

    add_single(out, "aliquot_leases_outstanding",
               "Sample jobs leased to workers and not yet returned.", MetricType::Gauge,
               double(c.leases_out()));
    add_single(out, "aliquot_store_write_failures_total",
               "Failed attempts to write the run record (SQLite, checkpoints, images), "
               "retries included.",
               MetricType::Counter, double(c.store_write_failures()));
    add_single(out, "aliquot_storage_warning",
               "1 while writes to the run record are failing.", MetricType::Gauge,
               c.storage_warning().empty() ? 0 : 1);
    add_single(out, "aliquot_render_memory_bytes",
               "Estimated bytes of the buffers of the renders in memory (what "
               "--memory-limit bounds).",
               MetricType::Gauge, double(c.memory_in_use()));
    add_single(out, "aliquot_renders_in_memory", "Renders whose buffers are in memory.",
               MetricType::Gauge, double(c.sessions_in_memory()));
    return out;
}

}  // namespace

struct FarmMetrics::Impl {
    Coordinator& coordinator;
    prometheus::Registry registry;
    prometheus::Family<prometheus::Histogram>& lease_family =
        prometheus::BuildHistogram()
            .Name("aliquot_lease_seconds")
            .Help(
                "Time to answer a worker's Lease (alone or riding on Complete), its "
                "long-poll wait included, by whether it handed out a job.")
            .Register(registry);
    prometheus::Histogram& lease_granted =
        lease_family.Add({{"outcome", "granted"}}, kLeaseBuckets);
    prometheus::Histogram& lease_empty =
        lease_family.Add({{"outcome", "none"}}, kLeaseBuckets);
    prometheus::Histogram& merge =
        prometheus::BuildHistogram()
            .Name("aliquot_merge_seconds")
            .Help(
                "Time to merge one result a worker returned with Complete (the end of "
                "its round, when it was the last job, included).")
            .Register(registry)
            .Add({}, kMergeBuckets);

    explicit Impl(Coordinator& c) : coordinator(c) {}
};

FarmMetrics::FarmMetrics(Coordinator& coordinator)
    : impl_(std::make_unique<Impl>(coordinator)) {}

FarmMetrics::~FarmMetrics() = default;

void FarmMetrics::observe_lease(double seconds, bool granted) {
    (granted ? impl_->lease_granted : impl_->lease_empty).Observe(seconds);
}

void FarmMetrics::observe_merge(double seconds) { impl_->merge.Observe(seconds); }

std::string FarmMetrics::scrape() {
    std::vector<MetricFamily> families = farm_state(impl_->coordinator);
    for (MetricFamily& f : impl_->registry.Collect()) families.push_back(std::move(f));
    return prometheus::TextSerializer().Serialize(families);
}

}  // namespace aliquot
