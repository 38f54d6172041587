// DenoisedStrategy: `denoised`, samples aimed at the error left after denoising. With
// optimal's pilot, floor and steered rounds, but each pixel's weight is the noise of the
// *denoised* image there: before each steered round the even-sample and odd-sample half
// images are denoised apart, and the difference of the two denoised halves is the noise
// the denoiser did not remove (the half-buffer idea Cycles applies to raw error, after
// reconstruction; the .cpp says why and from where).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "strategy.h"
#include "strategy_params.h"

namespace aliquot {

// A denoiser: the colour's rgb (linear HDR) denoised, an image of its size; albedo and
// normal are the render's mean first-hit guides, or null when it has none. Injected, so
// that tests run the strategy with a deterministic smoother and a render with Open Image
// Denoise (denoised_oidn.cpp). Must be deterministic: a render's bytes follow from its
// rounds. Throws std::runtime_error when it cannot denoise.
using DenoiseFunction =
    std::function<Image(const Image& colour, const Image* albedo, const Image* normal)>;

// Open Image Denoise through the denoise room, loaded once for the process; throws
// std::invalid_argument, saying what was tried and how to install it, when it is not
// there, so a render of method `denoised` is refused at once rather than failing later.
// Once `stop` (when given) turns true, a denoise gives up soon and throws.
DenoiseFunction oidn_denoise_function(
    std::shared_ptr<const std::atomic<bool>> stop = nullptr);

class DenoisedStrategy : public Strategy {
public:
    // Uses budget (or spp), min_spp, floor_fraction, steer_rounds (0 is taken as 1: no
    // doubling rounds, each would need its own denoised plan) and max_spp.
    // `stop`, when given, is what `denoise` watches: stop_work sets it.
    DenoisedStrategy(const StrategyParams& params, uint32_t width, uint32_t height,
                     DenoiseFunction denoise,
                     std::shared_ptr<std::atomic<bool>> stop = nullptr);

    std::string name() const override { return "denoised"; }
    std::optional<Round> next_round(const Accumulator& merged) override;
    // A steered round's plan, both OIDN passes in it, for the caller to make off its lock
    // (RenderSession runs it on a thread of its own): copies what the plan reads of
    // `merged` (read_round_end) and returns the work that plans from the copy. The round
    // is the one next_round would plan in place, bit for bit.
    std::function<void()> take_round_end(const Accumulator& merged) override;
    // A round end's OIDN passes give up (a render cancelled mid-plan waits for them).
    void stop_work() override {
        if (stop_) *stop_ = true;
    }
    uint64_t planned_samples() const override { return budget_; }
    nlohmann::json save_state() const override;
    void restore_state(const nlohmann::json& state) override;
    nlohmann::json outcome() const override;
    // OIDN's results depend much on its guides (albedo, normal): the render must trace
    // them.
    bool wants_first_hits() const override { return true; }
    void watch_first_hits(const AuxSums* first_hits) override {
        first_hits_ = first_hits;
    }

    // What a steered round's plan reads of the merged buffers, copied at the round end:
    // the half images (the means of each pixel's even and odd samples), the first-hit
    // guides (empty when the render keeps none), each pixel's samples and their total.
    // Kept from one round end to the next (56 bytes a pixel with guides, counted in the
    // render's memory estimate).
    struct RoundEndCopy {
        Image even, odd, albedo, normal;
        std::vector<uint64_t> samples;
        double spent = 0;
    };
    static void read_round_end(const Accumulator& merged, const AuxSums* first_hits,
                               RoundEndCopy& copy);

    // What a render of this method holds for its round ends beyond any render's buffers,
    // in bytes, at their peak: the copy kept from one round end to the next, the plan's
    // buffers while it is made, and one Open Image Denoise filter's working memory (the
    // .cpp has the measurements). The memory budget counts it (render_memory_estimate).
    static uint64_t round_end_memory(uint64_t pixels);

    // Per pixel, the standard deviation of one sample as seen through the denoiser:
    // sqrt(n_i * Var[denoised_i]), Var estimated from the two denoised halves and pooled
    // over the (2 radius + 1)^2 window by its median. What the weights n ∝ s^(2/3) are
    // made of. The guides are used when `first_hits` keeps them.
    static std::vector<double> denoised_sigma(const Accumulator& merged,
                                              const AuxSums* first_hits,
                                              const DenoiseFunction& denoise,
                                              uint32_t radius);
    // The same from a copy read_round_end made.
    static std::vector<double> denoised_sigma(const RoundEndCopy& copy,
                                              const DenoiseFunction& denoise,
                                              uint32_t radius);

private:
    // The next steered round's counts from round_end_; empty when the budget is spent.
    std::vector<uint32_t> steered_round() const;

    uint32_t width_, height_;
    uint64_t budget_;
    uint32_t min_spp_, cap_, steer_rounds_;
    uint64_t pilot_spp_;
    DenoiseFunction denoise_;
    std::shared_ptr<std::atomic<bool>> stop_;
    const AuxSums* first_hits_ = nullptr;  // the render's, while the strategy lives

    uint32_t rounds_ = 0;
    uint64_t issued_ = 0;
    bool finished_ = false;

    // The round end read (take_round_end) and the round its work planned from it, until
    // next_round hands that out. The work writes planned_ alone; nothing else reads it
    // until the caller has let the work finish.
    RoundEndCopy round_end_;
    bool round_end_read_ = false;
    std::optional<std::vector<uint32_t>> planned_;
};

}  // namespace aliquot
