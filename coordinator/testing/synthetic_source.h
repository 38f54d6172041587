// SyntheticImage: an in-process image function with known per-pixel mean and standard
// deviation, for testing strategies in milliseconds without Embree. Samples are a
// function of (seed, x, y, k) only, with the sample-index semantics of
// worker/job/sample_job.cpp.
#pragma once

#include <functional>

#include "accumulator.h"
#include "strategy.h"
#include "vec3.h"

namespace aliquot {

// One pixel's sample distribution. A sample is grey (R = G = B, so luminance = value):
// with probability nan_probability it is NaN (the accumulator counts it as 0); otherwise
// with probability firefly_probability it is firefly_value; otherwise it is uniform on
// mean ± sqrt(3) sigma (variance sigma^2; values may go below 0).
struct SyntheticPixel {
    double mean = 0;
    double sigma = 0;
    uint32_t rays = 1;  // rays each sample costs
    double firefly_probability = 0;
    double firefly_value = 0;
    double nan_probability = 0;
};

class SyntheticImage {
public:
    SyntheticImage(uint32_t width, uint32_t height, uint64_t seed = 1,
                   SyntheticPixel fill = {});

    uint32_t width() const { return width_; }
    uint32_t height() const { return height_; }
    size_t pixel_count() const { return pixels_.size(); }
    SyntheticPixel& at(uint32_t x, uint32_t y) { return pixels_[size_t(y) * width_ + x]; }
    const SyntheticPixel& at(size_t i) const { return pixels_[i]; }

    // What a render converges to at pixel i (NaN samples counted as 0), per channel.
    double expected(size_t i) const;
    // Standard deviation of one sample's value (as the accumulator sees it) at pixel i.
    double sigma(size_t i) const;

    Vec3 sample(uint32_t x, uint32_t y, uint64_t k) const;
    // Same contract as trace_sample_job: sums over k = first .. first+count-1.
    SampleJobResult trace(const SampleJob& job) const;

private:
    uint32_t width_, height_;
    uint64_t seed_;
    std::vector<SyntheticPixel> pixels_;
};

struct SyntheticRun {
    uint32_t rounds = 0;
    bool finished = false;  // the strategy said done before max_rounds
};

// Runs `strategy` against `image` as the farm would (cut_round, trace, merge) until it is
// done or has run `max_rounds` rounds. `after_round` sees each round once it is merged.
SyntheticRun run_synthetic(
    Strategy& strategy, const SyntheticImage& image, Accumulator& merged,
    uint32_t max_rounds = 100000,
    const std::function<void(const Round&, const Accumulator&)>& after_round = {});

// The seed's E against the known image: mean |estimate - expected| over pixels and RGB.
double mean_absolute_error(const Accumulator& merged, const SyntheticImage& image);

}  // namespace aliquot
