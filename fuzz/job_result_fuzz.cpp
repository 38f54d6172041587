// Fuzzes what a worker's Complete carries: the bytes are parsed as the v1.SampleJobResult
// message, converted by wire.h and completed into live render sessions whose first job
// they answer, as the gRPC service does. The other jobs of the round are answered
// correctly first, so a merged result ends the round: the round's error against a
// reference, the strategy's next plan from the merged buffers, and the image a client
// fetches all see what the result put there.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "aliquot.pb.h"
#include "render_session.h"
#include "scene_loader.h"
#include "wire.h"

namespace {

using aliquot::RenderSession;

// Adaptive's initial pass and Dammertz's first iteration are the same round (2 samples
// per pixel over 8x8), cut into one job, so one input (fuzz/corpus/job_result) answers
// the first job of both.
std::vector<aliquot::RenderSpec> specs() {
    aliquot::RenderSpec base;
    base.scene_name = "furnace";
    base.scene_json = *aliquot::builtin_scene_json("furnace");
    base.width = base.height = 8;
    base.seed = 1;
    aliquot::Image reference(8, 8);
    for (float& v : reference.rgb) v = 0.5f;
    base.reference = reference;

    aliquot::RenderSpec adaptive = base;
    adaptive.strategy.method = "adaptive";
    adaptive.strategy.initial_spp = 2;
    adaptive.strategy.budget = 8 * 8 * 8;
    adaptive.strategy.bucket_size = 4;

    aliquot::RenderSpec dammertz = base;
    dammertz.strategy.method = "dammertz";
    dammertz.strategy.samples_per_iteration = 2;
    dammertz.strategy.max_spp = 8;
    return {adaptive, dammertz};
}

aliquot::SampleJobResult answer(const aliquot::SampleJob& job) {
    aliquot::SampleJobResult r;
    r.rect = job.rect;
    r.pixels.resize(job.rect.size());
    for (size_t i = 0; i < r.pixels.size(); ++i) {
        r.pixels[i].samples = job.counts[i];
        r.pixels[i].even[0] = r.pixels[i].odd[0] = 0.25 * double(job.counts[i]);
        r.pixels[i].sum_sq_luminance = 0.01 * double(job.counts[i]);
    }
    return r;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    aliquot::v1::SampleJobResult message;
    if (!message.ParseFromArray(data, int(size))) return 0;
    // Read in place, as the gRPC service does: `message` outlives every merge below.
    aliquot::SampleJobResult result;
    try {
        aliquot::from_proto_in_place(message, result);
    } catch (const aliquot::WireError&) {
        return 0;  // the service rejects it and the job is traced again
    }
    static const std::vector<aliquot::RenderSpec> all = specs();
    const auto far = RenderSession::Clock::now() + std::chrono::hours(1);
    for (const aliquot::RenderSpec& spec : all) {
        RenderSession session("fuzz", spec, 0);
        session.start();
        std::vector<aliquot::SampleJob> jobs;
        while (auto job = session.issue(jobs.size() + 1, "w", far)) jobs.push_back(*job);
        for (size_t j = 1; j < jobs.size(); ++j)
            session.complete(j + 1, "w", answer(jobs[j]));
        session.complete(1, "w", result);
        // Whatever was merged is what a client fetches, AOVs included.
        session.merged().image(true);
    }
    return 0;
}
