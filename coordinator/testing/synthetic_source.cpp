#include "synthetic_source.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "round_cutter.h"
#include "sampler.h"

namespace aliquot {

namespace {

double uniform01(SampleRng& rng) { return double(rng.next_u32()) * 0x1p-32; }

}  // namespace

SyntheticImage::SyntheticImage(uint32_t width, uint32_t height, uint64_t seed,
                               SyntheticPixel fill)
    : width_(width),
      height_(height),
      seed_(seed),
      pixels_(size_t(width) * height, fill) {}

double SyntheticImage::expected(size_t i) const {
    const SyntheticPixel& p = pixels_[i];
    const double finite =
        (1 - p.firefly_probability) * p.mean + p.firefly_probability * p.firefly_value;
    return (1 - p.nan_probability) * finite;
}

double SyntheticImage::sigma(size_t i) const {
    const SyntheticPixel& p = pixels_[i];
    const double second =
        (1 - p.nan_probability) *
        ((1 - p.firefly_probability) * (p.sigma * p.sigma + p.mean * p.mean) +
         p.firefly_probability * p.firefly_value * p.firefly_value);
    const double m = expected(i);
    return std::sqrt(std::max(0.0, second - m * m));
}

Vec3 SyntheticImage::sample(uint32_t x, uint32_t y, uint64_t k) const {
    const SyntheticPixel& p = pixels_[size_t(y) * width_ + x];
    // Three draws per sample whatever the outcome, so the k-th sample is the same
    // whatever the probabilities of the other branches.
    SampleRng rng(seed_, x, y, k);
    const double u_nan = uniform01(rng), u_firefly = uniform01(rng), u = uniform01(rng);
    if (u_nan < p.nan_probability) return Vec3(std::numeric_limits<float>::quiet_NaN());
    if (u_firefly < p.firefly_probability) return Vec3(float(p.firefly_value));
    return Vec3(float(p.mean + p.sigma * std::sqrt(3.0) * (2 * u - 1)));
}

SampleJobResult SyntheticImage::trace(const SampleJob& job) const {
    const PixelRect& r = job.rect;
    if (job.counts.size() != r.size() || job.first_sample.size() != r.size())
        throw std::invalid_argument(
            "synthetic job: per-pixel arrays do not match its rectangle");
    if (uint64_t(r.x) + r.width > width_ || uint64_t(r.y) + r.height > height_)
        throw std::invalid_argument("synthetic job: rectangle lies outside the image");
    SampleJobResult result;
    result.rect = r;
    result.pixels.resize(r.size());
    for (uint32_t row = 0; row < r.height; ++row) {
        for (uint32_t col = 0; col < r.width; ++col) {
            const size_t i = size_t(row) * r.width + col;
            const uint32_t x = r.x + col, y = r.y + row;
            const uint32_t rays = pixels_[size_t(y) * width_ + x].rays;
            for (uint64_t k = job.first_sample[i];
                 k < job.first_sample[i] + job.counts[i]; ++k)
                add_sample(result.pixels[i], k, sample(x, y, k), rays);
        }
    }
    return result;
}

SyntheticRun run_synthetic(
    Strategy& strategy, const SyntheticImage& image, Accumulator& merged,
    uint32_t max_rounds,
    const std::function<void(const Round&, const Accumulator&)>& after_round) {
    if (merged.width() != image.width() || merged.height() != image.height())
        throw std::invalid_argument(
            "run_synthetic: accumulator and image differ in size");
    SyntheticRun run;
    while (run.rounds < max_rounds) {
        const std::optional<Round> round = strategy.next_round(merged);
        if (!round) {
            run.finished = true;
            break;
        }
        if (round->spp.size() != image.pixel_count())
            throw std::logic_error(strategy.name() + ": round does not cover the image");
        for (const SampleJob& job : cut_round(*round, merged))
            merged.merge(image.trace(job));
        ++run.rounds;
        if (after_round) after_round(*round, merged);
    }
    return run;
}

double mean_absolute_error(const Accumulator& merged, const SyntheticImage& image) {
    double sum = 0;
    for (size_t i = 0; i < merged.pixel_count(); ++i) {
        double rgb[3];
        merged.mean(i, rgb);
        for (int c = 0; c < 3; ++c) sum += std::abs(rgb[c] - image.expected(i));
    }
    return merged.pixel_count() ? sum / (3.0 * double(merged.pixel_count())) : 0.0;
}

}  // namespace aliquot
