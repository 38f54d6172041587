// A `denoised` render's round end (issue 33's review): its two denoiser passes ran on the
// merging thread under the render's lock (minutes at 8192x8192), and every lease scan
// that reached the render waited on it. Now they run on the session's own thread while
// the lock is free: another render's leases and merges go on, and a scan of the render
// itself finds nothing there and returns. A gated denoiser stands for a long OIDN run. No
// test here bounds a time: the waits are generous and fail on a deadlock only.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <stdexcept>
#include <thread>

#include "checkpoint.h"
#include "denoised_strategy.h"
#include "farm_test_results.h"
#include "lease_scan.h"
#include "scene_loader.h"

namespace aliquot {
namespace {

constexpr auto kDeadlock = std::chrono::seconds(60);

// A denoiser (the identity) whose calls wait until open() once it is shut, or until
// `stop` (when given) turns true, and then throw, as OIDN's do; entered() is ready once a
// call has begun. Opened when it goes, so no thread is left waiting.
class GatedDenoiser {
public:
    GatedDenoiser() : state_(std::make_shared<State>()) {
        state_->opened = state_->open.get_future().share();
        state_->began = state_->entered.get_future().share();
    }
    ~GatedDenoiser() { open(); }
    GatedDenoiser(const GatedDenoiser&) = delete;
    GatedDenoiser& operator=(const GatedDenoiser&) = delete;

    DenoiseFunction function(std::shared_ptr<const std::atomic<bool>> stop = {}) const {
        return [state = state_, stop](const Image& in, const Image*, const Image*) {
            if (!state->entered_once.exchange(true)) state->entered.set_value();
            while (state->opened.wait_for(std::chrono::milliseconds(1)) !=
                   std::future_status::ready)
                if (stop && *stop) throw std::runtime_error("denoising stopped");
            return in;
        };
    }
    std::shared_future<void> entered() const { return state_->began; }
    void open() {
        if (!state_->open_once.exchange(true)) state_->open.set_value();
    }

private:
    struct State {
        std::promise<void> open, entered;
        std::shared_future<void> opened, began;
        std::atomic<bool> open_once = false, entered_once = false;
    };
    std::shared_ptr<State> state_;
};

RenderSpec spec_of(const char* method, uint32_t side, uint32_t spp) {
    RenderSpec spec;
    spec.scene_name = "cornell-box";
    spec.scene_json = self_contained_scene_json("cornell-box");
    spec.width = spec.height = side;
    spec.strategy.method = method;
    spec.strategy.spp = spp;
    return spec;
}

SlotPtr slot_of(std::unique_ptr<RenderSession> session) {
    auto slot = std::make_shared<RenderSlot>();
    slot->session = std::move(session);
    slot->session->start();
    return slot;
}

class DenoisedRoundEnd : public ::testing::Test {
protected:
    // A lease from `slots` as the Coordinator asks for one (lease_scan.h).
    std::optional<LeaseGrant> lease(const std::vector<SlotPtr>& slots) {
        LeaseAsk ask;
        ask.lease_id = ++last_lease;
        ask.worker = "w";
        ask.lease_time = std::chrono::minutes(10);
        ask.alive = &alive;
        ask.cores = 1;
        return scan_for_a_job(slots, ask).grant;
    }
    // Merges `grant`'s result under its render's lock, as Coordinator::complete does.
    static CompleteStatus complete(RenderSlot& slot, const LeaseGrant& grant) {
        std::lock_guard render(slot.mutex);
        return slot.session->complete(grant.lease_id, "w", made_up_result(grant)).status;
    }
    // Leases and merges `slot`'s jobs until none is to be had now.
    void merge_all_now(const SlotPtr& slot) {
        while (const std::optional<LeaseGrant> grant = lease({slot}))
            ASSERT_EQ(complete(*slot, *grant), CompleteStatus::Merged);
    }

    std::set<std::string> alive;
    uint64_t last_lease = 0;
};

TEST_F(DenoisedRoundEnd, OtherRendersAndItsOwnLeaseScanGoOnWhileItsPlanIsMade) {
    const RenderSpec spec = spec_of("denoised", 16, 8);
    GatedDenoiser gate;
    const SlotPtr denoised = slot_of(std::make_unique<RenderSession>(
        "denoised", spec, 0,
        std::make_unique<DenoisedStrategy>(spec.strategy, spec.width, spec.height,
                                           gate.function())));
    const SlotPtr other =
        slot_of(std::make_unique<RenderSession>("other", spec_of("uniform", 4, 1), 0));
    // Opened before the sessions go (declared after them): the session waits for its
    // plan when it goes, and the plan for the gate.
    struct Opener {
        GatedDenoiser& gate;
        ~Opener() { gate.open(); }
    } opener{gate};

    // The pilot: every job but the last merged; the last ends the round, whose plan
    // then waits at the gate.
    std::vector<LeaseGrant> pilot;
    while (std::optional<LeaseGrant> grant = lease({denoised})) pilot.push_back(*grant);
    ASSERT_FALSE(pilot.empty());
    for (size_t j = 0; j + 1 < pilot.size(); ++j)
        ASSERT_EQ(complete(*denoised, pilot[j]), CompleteStatus::Merged);
    auto last =
        std::async(std::launch::async, [&] { return complete(*denoised, pilot.back()); });
    ASSERT_EQ(gate.entered().wait_for(kDeadlock), std::future_status::ready)
        << "the round end did not denoise";
    // Before, the merge that ended the round ran both passes under the render's lock
    // and returned only once the gate opened.
    const bool returned = last.wait_for(kDeadlock) == std::future_status::ready;
    if (!returned) gate.open();
    ASSERT_TRUE(returned) << "the round end's merge waited for the denoiser";
    EXPECT_EQ(last.get(), CompleteStatus::Merged);

    // While the plan waits at the gate: the render's lock is free, a lease scan that
    // reaches it passes on to another render's job (and that merges), and one of the
    // render alone finds nothing yet and returns.
    {
        std::unique_lock free(denoised->mutex, std::try_to_lock);
        EXPECT_TRUE(free.owns_lock());
    }
    const std::optional<LeaseGrant> elsewhere = lease({denoised, other});
    ASSERT_TRUE(elsewhere);
    EXPECT_EQ(elsewhere->render_id, "other");
    EXPECT_EQ(complete(*other, *elsewhere), CompleteStatus::Merged);
    EXPECT_EQ(other->session->state(), RenderState::Done);
    EXPECT_FALSE(lease({denoised}));
    {
        std::lock_guard render(denoised->mutex);
        EXPECT_EQ(denoised->session->state(), RenderState::Running);
        EXPECT_TRUE(denoised->session->has_pending());  // workers keep asking
        EXPECT_EQ(denoised->session->rounds_done(), 1u);
    }

    // Opened, the plan ends; the tick's sweep announces it and the next lease opens the
    // round it made. The render then runs to its end, each round end planned alike.
    gate.open();
    const auto give_up = std::chrono::steady_clock::now() + kDeadlock;
    bool announced = false;
    while (!announced && std::chrono::steady_clock::now() < give_up) {
        announced = sweep_leases({denoised}, RenderSession::Clock::now()).opened_ahead;
        if (!announced) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ASSERT_TRUE(announced);
    for (bool done = false; !done && std::chrono::steady_clock::now() < give_up;) {
        merge_all_now(denoised);
        {
            std::lock_guard render(denoised->mutex);
            done = denoised->session->finished();
        }
        if (!done) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::lock_guard render(denoised->mutex);
    EXPECT_EQ(denoised->session->state(), RenderState::Done);
    EXPECT_GT(denoised->session->rounds_done(), 2u);
    EXPECT_EQ(denoised->session->merged().total_samples(), 8u * 16 * 16);
}

// A render cancelled while its round end denoises: the denoiser is told to stop
// (Strategy::stop_work), so the cancel, under the render's lock, does not wait out a plan
// of minutes that no one will use.
TEST_F(DenoisedRoundEnd, ACancelStopsThePlanItWouldOtherwiseWaitFor) {
    const RenderSpec spec = spec_of("denoised", 16, 8);
    GatedDenoiser gate;
    auto stop = std::make_shared<std::atomic<bool>>(false);
    const SlotPtr denoised = slot_of(std::make_unique<RenderSession>(
        "denoised", spec, 0,
        std::make_unique<DenoisedStrategy>(spec.strategy, spec.width, spec.height,
                                           gate.function(stop), stop)));
    struct Opener {
        GatedDenoiser& gate;
        ~Opener() { gate.open(); }
    } opener{gate};
    merge_all_now(denoised);  // the pilot; its end's plan waits at the gate
    ASSERT_EQ(gate.entered().wait_for(kDeadlock), std::future_status::ready);
    auto cancel = std::async(std::launch::async, [&] {
        std::lock_guard render(denoised->mutex);
        denoised->session->cancel();
    });
    const bool returned = cancel.wait_for(kDeadlock) == std::future_status::ready;
    if (!returned) gate.open();
    ASSERT_TRUE(returned) << "the cancel waited for the denoiser";
    std::lock_guard render(denoised->mutex);
    EXPECT_EQ(denoised->session->state(), RenderState::Cancelled);
}

// A render resumed from a checkpoint plans its first round (a steered one) off the lock
// too, from start(), which the Coordinator calls under its own lock; it ends with the
// bytes of a render never interrupted.
TEST_F(DenoisedRoundEnd, AResumedRenderEndsWithTheBytesOfAnUninterruptedOne) {
    const RenderSpec spec = spec_of("denoised", 16, 8);
    const auto session = [&] {
        return std::make_unique<RenderSession>(
            "denoised", spec, 0,
            std::make_unique<DenoisedStrategy>(
                spec.strategy, spec.width, spec.height,
                [](const Image& in, const Image*, const Image*) { return in; }));
    };
    // Leases and merges until the render ends, the plans of its round ends in between.
    const auto run_to_end = [&](const SlotPtr& slot) {
        const auto give_up = std::chrono::steady_clock::now() + kDeadlock;
        for (bool done = false; !done && std::chrono::steady_clock::now() < give_up;) {
            merge_all_now(slot);
            std::lock_guard render(slot->mutex);
            done = slot->session->finished();
        }
        std::lock_guard render(slot->mutex);
        EXPECT_EQ(slot->session->state(), RenderState::Done);
        return slot->session->merged().image(true).rgb;
    };

    Checkpoint saved;
    auto interrupted = std::make_shared<RenderSlot>();
    interrupted->session = session();
    interrupted->session->on_round = [&](RenderSession& r, const RoundSummary& round) {
        if (round.index != 2) return;
        saved.merged.copy_from(r.merged());
        saved.aux = r.aux();
        saved.strategy_state = r.strategy().save_state();
        saved.rounds_done = r.rounds_done();
    };
    interrupted->session->start();
    const std::vector<float> whole = run_to_end(interrupted);
    ASSERT_EQ(saved.rounds_done, 3u);

    auto resumed = std::make_shared<RenderSlot>();
    resumed->session = session();
    resumed->session->restore(std::move(saved.merged), saved.strategy_state,
                              saved.rounds_done, 0, {}, std::move(saved.aux));
    resumed->session->start();
    EXPECT_EQ(run_to_end(resumed), whole);
}

}  // namespace
}  // namespace aliquot
