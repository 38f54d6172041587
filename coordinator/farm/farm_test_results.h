// What the farm's tests hand the coordinator: a small render, and results for a leased
// job made from the job alone, so that a render's bytes depend on its spec only,
// whichever worker or thread returns them.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <functional>
#include <future>

#include "coordinator.h"
#include "lease.h"
#include "render_spec.h"
#include "scene_loader.h"

namespace aliquot {

// 4x4 pixels of the Cornell box, one sample each: one round of one job.
inline RenderSpec small_test_spec() {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = spec.height = 4;
    spec.strategy.method = "uniform";
    spec.strategy.spp = 1;
    return spec;
}

// A valid result for `grant`: its sample counts, zero radiance; for a job that asks for
// first hits (a render that keeps them), an albedo of 0.25 and a normal of +y a sample.
inline SampleJobResult zero_result(const LeaseGrant& grant) {
    SampleJobResult result;
    result.rect = grant.job.rect;
    result.pixels.assign(grant.job.counts.size(), PixelSums{});
    if (grant.job.aux) result.first_hits.assign(grant.job.counts.size(), FirstHitSums{});
    for (size_t i = 0; i < grant.job.counts.size(); ++i) {
        result.pixels[i].samples = grant.job.counts[i];
        if (!grant.job.aux) continue;
        const double n = double(grant.job.counts[i]);
        for (int c = 0; c < 3; ++c) result.first_hits[i].albedo[c] = 0.25 * n;
        result.first_hits[i].normal[1] = n;
    }
    return result;
}

// A result that depends on its job alone (pixel, first sample, count), with noise that
// varies over the image, so adaptive methods decide differently pixel by pixel.
inline SampleJobResult made_up_result(const LeaseGrant& grant) {
    SampleJobResult result = zero_result(grant);
    for (uint32_t y = 0; y < result.rect.height; ++y)
        for (uint32_t x = 0; x < result.rect.width; ++x) {
            const size_t i = size_t(y) * result.rect.width + x;
            const double px = result.rect.x + x, py = result.rect.y + y;
            const double n = double(grant.job.counts[i]);
            const double k = double(grant.job.first_sample[i]);
            const double noise = 0.1 + 0.4 * std::fabs(std::sin(0.7 * px + 0.3 * py + k));
            PixelSums& p = result.pixels[i];
            for (int c = 0; c < 3; ++c) {
                p.even[c] = 0.5 * n * (0.3 + noise);
                p.odd[c] = 0.5 * n * (0.3 - noise);
            }
            p.sum_sq_luminance = n * (0.09 + noise * noise);
            p.rays = 3 * grant.job.counts[i];
        }
    return result;
}

// side x side pixels of the Cornell box by `method`, `spp` samples a pixel (uniform) or
// as budget (the others).
inline RenderSpec square_test_spec(const char* method, uint32_t side, uint32_t spp) {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = spec.height = side;
    spec.seed = 7;
    spec.strategy.method = method;
    if (spec.strategy.method == "uniform") {
        spec.strategy.spp = spp;
    } else {
        spec.strategy.spp = 0;
        spec.strategy.budget = uint64_t(side) * side * spp;
    }
    return spec;
}

// `spec` rendered by one worker alone (made_up_result), to the end: what any farm of
// workers must give, byte for byte.
inline Image rendered_alone(const RenderSpec& spec) {
    Coordinator c(CoordinatorOptions{});
    const std::string id = c.submit(spec);
    const std::string session = c.register_worker("alone", 1).session;
    while (!is_terminal(c.info(id)->state))
        if (auto grant = c.lease(session, std::chrono::milliseconds(20)))
            c.complete(session, grant->lease_id, made_up_result(*grant));
    EXPECT_EQ(c.info(id)->state, RenderState::Done);
    return *c.image(id, true);
}

// Holds the first merge that reaches its add (Coordinator::set_while_adding_for_test)
// until released.
struct HeldAdd {
    std::promise<void> reached, release;
    std::shared_future<void> released = release.get_future().share();
    std::atomic<bool> first{true};

    std::function<void(size_t)> hook() {
        return [this](size_t) {
            if (!first.exchange(false)) return;
            reached.set_value();
            released.wait();
        };
    }
};

// Starts merging `grant`'s made-up result on a thread of its own and returns once its add
// is held by `held` (hooked on render `id`); the future gives the merge's status.
inline std::future<CompleteStatus> merge_held(Coordinator& c, const std::string& id,
                                              const std::string& session,
                                              const LeaseGrant& grant, HeldAdd& held) {
    c.set_while_adding_for_test(id, held.hook());
    std::future<CompleteStatus> merge =
        std::async(std::launch::async, [&c, &session, &grant] {
            return c.complete(session, grant.lease_id, made_up_result(grant)).status;
        });
    held.reached.get_future().wait();
    return merge;
}

}  // namespace aliquot
