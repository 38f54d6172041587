#include "accumulator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>

#include "aov_channels.h"
#include "bands.h"
#include "vec3.h"

namespace aliquot {

namespace {

// A merged pixel's sums stay within this many times its sample count: its mean and its
// halves' means stay below 3e30 (each half holds at least a third of the samples from two
// on), far inside float32 (3.4e38), the type of the EXR; so does its mean's variance (the
// "variance.Y" layer), which is at most sum_sq_luminance / (n (n - 1)). No physical
// radiance comes near it, and a pixel's sum cannot pass 1e30 x 2^64 = 2e49, whose square
// (the variance estimate squares sums) is a finite double. A sum under such a bound can
// still give an infinite float when divided by a sample count of 1: the bound is on the
// mean, not on the sum.
constexpr double kMaxMeanPerSample = 1e30;

// What a result's own sums may be, a sample, for it to be merged without looking at the
// buffers (see Accumulator::roomy_): a quarter of the bound.
constexpr double kRoomyResultPerSample = 0.25 * kMaxMeanPerSample;

// Whether a result's pixel is within kRoomyResultPerSample (a pixel of no samples: all
// zero). NaN fails. No branches.
bool roomy(const PixelSums& src) {
    const double bound = kRoomyResultPerSample * double(src.samples);
    bool ok = std::abs(src.sum_sq_luminance) <= bound;
    for (int c = 0; c < 3; ++c) {
        ok &= std::abs(src.even[c]) <= bound;
        ok &= std::abs(src.odd[c]) <= bound;
    }
    return ok;
}

// Whether merging `src` into `dst` keeps every sum finite and within the bound. NaN and
// infinities fail the comparisons. No branches: the pass over a result vectorises.
bool stays_bounded(const PixelSums& dst, const PixelSums& src) {
    const double bound = kMaxMeanPerSample * double(dst.samples + src.samples);
    bool ok = std::abs(dst.sum_sq_luminance + src.sum_sq_luminance) <= bound;
    for (int c = 0; c < 3; ++c) {
        ok &= std::abs(dst.even[c] + src.even[c]) <= bound;
        ok &= std::abs(dst.odd[c] + src.odd[c]) <= bound;
    }
    return ok;
}

// A merged pixel's half difference (see half_difference()), from the pixel itself: the
// merge has it in registers. The same operations in the same order as half_means().
double half_difference_of(const PixelSums& p) {
    if (p.samples < 2) return -1.0;  // the odd half has no sample yet
    const double n_even = double((p.samples + 1) / 2), n_odd = double(p.samples / 2);
    return (std::abs(p.even[0] / n_even - p.odd[0] / n_odd) +
            std::abs(p.even[1] / n_even - p.odd[1] / n_odd) +
            std::abs(p.even[2] / n_even - p.odd[2] / n_odd)) /
           3.0;
}

// A merged pixel's sample variance of one sample's luminance (see luminance_variance()).
double luminance_variance_of(const PixelSums& p) {
    if (p.samples < 2) return 0.0;
    const double n = double(p.samples);
    const double sum =
        luminance(p.even[0] + p.odd[0], p.even[1] + p.odd[1], p.even[2] + p.odd[2]);
    const double var = (p.sum_sq_luminance - sum * sum / n) / (n - 1.0);
    return var > 0 ? var : 0.0;  // cancellation can leave a tiny negative
}

// Two pixels' half differences and luminance variances at once, each lane the very
// operations of half_difference_of() and luminance_variance_of() (IEEE division and
// the rest lane by lane: the same bits). The merge's time went to its nine divisions a
// pixel, waited on one after the other; two lanes halve their count.
using Lanes = double __attribute__((vector_size(16)));
using LaneBits = uint64_t __attribute__((vector_size(16)));

Lanes abs_of(Lanes v) {
    const LaneBits magnitude = {~(uint64_t(1) << 63), ~(uint64_t(1) << 63)};
    return Lanes(LaneBits(v) & magnitude);  // std::abs: -0.0 becomes +0.0 too
}

void derive_two(const PixelSums& a, const PixelSums& b, double half_difference[2],
                double variance[2]) {
    // A lane below two samples divides by zero; its result is replaced below, as the
    // scalar functions return before dividing.
    const Lanes n_even = {double((a.samples + 1) / 2), double((b.samples + 1) / 2)};
    const Lanes n_odd = {double(a.samples / 2), double(b.samples / 2)};
    Lanes channel[3], total[3];
    for (int c = 0; c < 3; ++c) {
        const Lanes even = {a.even[c], b.even[c]}, odd = {a.odd[c], b.odd[c]};
        channel[c] = abs_of(even / n_even - odd / n_odd);
        total[c] = even + odd;
    }
    const Lanes difference = (channel[0] + channel[1] + channel[2]) / 3.0;
    const Lanes n = {double(a.samples), double(b.samples)};
    const Lanes sum = kLuminanceWeights[0] * total[0] + kLuminanceWeights[1] * total[1] +
                      kLuminanceWeights[2] * total[2];
    const Lanes sum_sq = {a.sum_sq_luminance, b.sum_sq_luminance};
    const Lanes var = (sum_sq - sum * sum / n) / (n - 1.0);
    half_difference[0] = a.samples < 2 ? -1.0 : difference[0];
    half_difference[1] = b.samples < 2 ? -1.0 : difference[1];
    variance[0] = a.samples < 2 ? 0.0 : (var[0] > 0 ? var[0] : 0.0);
    variance[1] = b.samples < 2 ? 0.0 : (var[1] > 0 ? var[1] : 0.0);
}

// Whether a result's pixel is what its job asked for (Accumulator::check's `counts`). No
// branches: the pass over a result vectorises.
bool as_asked(const PixelSums& p, uint32_t count) {
    constexpr double kLargest = std::numeric_limits<double>::max();  // NaN fails <=
    bool ok = p.samples == count;
    ok &= p.nonfinite <= p.samples;
    bool finite = p.sum_sq_luminance >= 0 && p.sum_sq_luminance <= kLargest;
    bool zero = p.sum_sq_luminance == 0 && p.rays == 0 && p.nonfinite == 0;
    for (int c = 0; c < 3; ++c) {
        finite &= std::abs(p.even[c]) <= kLargest;
        finite &= std::abs(p.odd[c]) <= kLargest;
        zero &= p.even[c] == 0 && p.odd[c] == 0;
    }
    return ok & finite & (p.samples != 0 || zero);
}

// as_asked for a roomy pixel (within a quarter of the bound a sample: finite sums, and
// all zero without samples), so what roomy() does not already say. No branches.
bool roomy_as_asked(const PixelSums& p, uint32_t count) {
    return (p.samples == count) & (p.nonfinite <= p.samples) & (p.sum_sq_luminance >= 0) &
           ((p.samples != 0) | ((p.rays | p.nonfinite) == 0));
}

// Why a result is not what its job asked for: the first pixel that is not, as the
// render session said it before the check joined the merge's pass.
std::string why_not_as_asked(const SampleJobResult& result, const uint32_t* counts) {
    for (size_t i = 0; i < result.pixels.size(); ++i) {
        const PixelSums& p = result.pixels[i];
        if (p.samples != counts[i])
            return "pixel " + std::to_string(i) + " has " + std::to_string(p.samples) +
                   " samples, job asked for " + std::to_string(counts[i]);
        if (p.nonfinite > p.samples) return "more non-finite samples than samples";
        if (p.samples == 0 && p != PixelSums{})
            return "pixel " + std::to_string(i) + " has no samples but non-zero sums";
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(p.even[c]) || !std::isfinite(p.odd[c]))
                return "non-finite sum at pixel " + std::to_string(i);
        if (!std::isfinite(p.sum_sq_luminance) || p.sum_sq_luminance < 0)
            return "bad sum of squares at pixel " + std::to_string(i);
    }
    return "result differs from its job";  // as_asked and this disagree: never
}

}  // namespace

Accumulator::Accumulator(uint32_t width, uint32_t height)
    : width_(width),
      height_(height),
      pixels_(size_t(width) * height),
      samples_(pixels_.size()),
      rays_(pixels_.size()),
      half_difference_(pixels_.size()),
      luminance_variance_(pixels_.size()) {
    // The one buffer whose start is not zero: below two samples a pixel has no half
    // difference.
    std::fill(half_difference_.begin(), half_difference_.end(), -1.0);
}

Accumulator::Accumulator(Accumulator&& other) noexcept { *this = std::move(other); }

Accumulator& Accumulator::operator=(Accumulator&& other) noexcept {
    if (this == &other) return *this;
    width_ = std::exchange(other.width_, 0);
    height_ = std::exchange(other.height_, 0);
    pixels_ = std::move(other.pixels_);
    samples_ = std::move(other.samples_);
    rays_ = std::move(other.rays_);
    half_difference_ = std::move(other.half_difference_);
    luminance_variance_ = std::move(other.luminance_variance_);
    total_samples_ = other.total_samples_.exchange(0);
    total_rays_ = other.total_rays_.exchange(0);
    total_nonfinite_ = other.total_nonfinite_.exchange(0);
    roomy_ = other.roomy_.exchange(true);
    return *this;
}

void Accumulator::touch_pages() {
    pixels_.touch();
    samples_.touch();
    rays_.touch();
    half_difference_.touch();
    luminance_variance_.touch();
}

namespace {

bool check_as_asked_whole(const SampleJobResult& result, const uint32_t* counts) {
    bool asked = true;
    for (size_t i = 0; i < result.pixels.size(); ++i)
        asked &= as_asked(result.pixels[i], counts[i]);
    return asked;
}

}  // namespace

ResultTotals check_as_asked(const SampleJobResult& result, const uint32_t* counts) {
    ResultTotals totals;
    bool asked = true;
    for (const PixelSums& p : result.pixels) {
        totals.samples += p.samples;
        totals.rays += p.rays;
        totals.nonfinite += p.nonfinite;
        asked &= as_asked(p, *counts++);
    }
    if (!asked) throw MergeError(why_not_as_asked(result, counts - result.pixels.size()));
    return totals;
}

void Accumulator::merge(const SampleJobResult& result) { add(result, check(result)); }

ResultTotals Accumulator::check(const SampleJobResult& result, const uint32_t* counts) {
    const PixelRect& r = result.rect;
    if (uint64_t(r.x) + r.width > width_ || uint64_t(r.y) + r.height > height_)
        throw MergeError("result rectangle lies outside the " + std::to_string(width_) +
                         "x" + std::to_string(height_) + " image");
    if (result.pixels.size() != r.size())
        throw MergeError("result has " + std::to_string(result.pixels.size()) +
                         " pixels for a rectangle of " + std::to_string(r.size()));
    // One pass over the result: its totals, whether it is what its job asked for, and
    // whether it is roomy. While every merged sum is within 3/4 of the bound a sample
    // (roomy_), a result within 1/4 of it cannot take a pixel past 3/4 (|d + s| <= 3/4
    // n_d + 1/4 n_s <= 3/4 (n_d + n_s), rounding far inside the margin left to the
    // bound), so it is merged after this pass over its own sums alone, not the
    // buffers' as well. Any other result is checked against the buffers, as always,
    // and ends the shortcut for good. Which results are refused does not change.
    ResultTotals totals;
    bool fits = true, asked = true;
    const PixelSums* const pixels = result.pixels.data();
    const size_t n = result.pixels.size();
    const auto pass = [&](auto with_counts) {
        for (size_t i = 0; i < n; ++i) {
            totals.samples += pixels[i].samples;
            totals.rays += pixels[i].rays;
            totals.nonfinite += pixels[i].nonfinite;
            fits &= roomy(pixels[i]);
            if constexpr (decltype(with_counts)::value)
                asked &= roomy_as_asked(pixels[i], counts[i]);
        }
    };
    if (counts)
        pass(std::true_type{});
    else
        pass(std::false_type{});
    // A result with a pixel that is not roomy is looked at again whole (rare: sums near
    // the bound, or a worker's error).
    if (counts && !fits) asked = check_as_asked_whole(result, counts);
    if (!asked) throw MergeError(why_not_as_asked(result, counts));
    if (!fits || !roomy_.load(std::memory_order_relaxed)) {
        check_finite_after(result);
        roomy_.store(false, std::memory_order_relaxed);
    }
    return totals;
}

void Accumulator::add(const SampleJobResult& result, const ResultTotals& totals) {
    const PixelRect& r = result.rect;
    // A row at a time through plain pointers: stores to the uint64_t arrays could
    // otherwise alias what the loop reads, and every pixel would reload it.
    for (uint32_t row = 0; row < r.height; ++row) {
        const size_t first = size_t(r.y + row) * width_ + r.x;
        const PixelSums* src = result.pixels.data() + size_t(row) * r.width;
        PixelSums* dst = pixels_.data() + first;
        uint64_t* const pixel_samples = samples_.data() + first;
        uint64_t* const pixel_rays = rays_.data() + first;
        double* const half_difference = half_difference_.data() + first;
        double* const variance = luminance_variance_.data() + first;
        for (uint32_t col = 0; col < r.width; ++col) {
            const PixelSums& s = src[col];
            PixelSums& d = dst[col];
            for (int c = 0; c < 3; ++c) {
                d.even[c] += s.even[c];
                d.odd[c] += s.odd[c];
            }
            d.sum_sq_luminance += s.sum_sq_luminance;
            d.samples += s.samples;
            d.rays += s.rays;
            d.nonfinite += s.nonfinite;
            pixel_samples[col] = d.samples;
            pixel_rays[col] = d.rays;
        }
        // The derived values from the row just merged, still in cache, two at a time.
        uint32_t col = 0;
        for (; col + 1 < r.width; col += 2)
            derive_two(dst[col], dst[col + 1], half_difference + col, variance + col);
        if (col < r.width) {
            half_difference[col] = half_difference_of(dst[col]);
            variance[col] = luminance_variance_of(dst[col]);
        }
    }
    total_samples_.fetch_add(totals.samples, std::memory_order_relaxed);
    total_rays_.fetch_add(totals.rays, std::memory_order_relaxed);
    total_nonfinite_.fetch_add(totals.nonfinite, std::memory_order_relaxed);
}

void Accumulator::check_finite_after(const SampleJobResult& result) const {
    const PixelRect& r = result.rect;
    // One pass that only looks, the result's pixels checked as a whole before any is
    // added: a refused result leaves the buffers exactly as they were.
    bool ok = true;
    for (uint32_t row = 0; row < r.height; ++row) {
        const PixelSums* src = result.pixels.data() + size_t(row) * r.width;
        const PixelSums* dst = pixels_.data() + size_t(r.y + row) * width_ + r.x;
        for (uint32_t col = 0; col < r.width; ++col)
            ok &= stays_bounded(dst[col], src[col]);
    }
    if (ok) return;
    for (uint32_t row = 0; row < r.height; ++row)
        for (uint32_t col = 0; col < r.width; ++col)
            if (!stays_bounded(pixels_[size_t(r.y + row) * width_ + r.x + col],
                               result.pixels[size_t(row) * r.width + col]))
                throw MergeError("merging would make pixel (" +
                                 std::to_string(r.x + col) + ", " +
                                 std::to_string(r.y + row) +
                                 ")'s sums non-finite or larger than 1e30 a sample");
}

void Accumulator::mean(size_t i, double rgb[3]) const {
    const PixelSums& p = pixels_[i];
    const double inv = p.samples ? 1.0 / double(p.samples) : 0.0;
    for (int c = 0; c < 3; ++c) rgb[c] = (p.even[c] + p.odd[c]) * inv;
}

void Accumulator::copy_from(const Accumulator& other) {
    if (this == &other) return;
    width_ = other.width_;
    height_ = other.height_;
    total_samples_ = other.total_samples();
    total_rays_ = other.total_rays();
    total_nonfinite_ = other.total_nonfinite();
    roomy_ = other.roomy_.load(std::memory_order_relaxed);
    pixels_.resize(other.pixels_.size());
    samples_.resize(other.samples_.size());
    rays_.resize(other.rays_.size());
    half_difference_.resize(other.half_difference_.size());
    luminance_variance_.resize(other.luminance_variance_.size());
    for_each_band(pixels_.size(), kBandPixels, [&](size_t, size_t begin, size_t end) {
        std::copy(other.pixels_.begin() + begin, other.pixels_.begin() + end,
                  pixels_.begin() + begin);
        std::copy(other.samples_.begin() + begin, other.samples_.begin() + end,
                  samples_.begin() + begin);
        std::copy(other.rays_.begin() + begin, other.rays_.begin() + end,
                  rays_.begin() + begin);
        std::copy(other.half_difference_.begin() + begin,
                  other.half_difference_.begin() + end, half_difference_.begin() + begin);
        std::copy(other.luminance_variance_.begin() + begin,
                  other.luminance_variance_.begin() + end,
                  luminance_variance_.begin() + begin);
    });
}

void Accumulator::half_means(size_t i, double even[3], double odd[3]) const {
    const PixelSums& p = pixels_[i];
    // Sample indices of a pixel run 0, 1, 2, ... across rounds, so the even half holds
    // ceil(n/2) of them and the odd half floor(n/2).
    const uint64_t n_even = (p.samples + 1) / 2, n_odd = p.samples / 2;
    for (int c = 0; c < 3; ++c) {
        even[c] = n_even ? p.even[c] / double(n_even) : 0.0;
        odd[c] = n_odd ? p.odd[c] / double(n_odd) : 0.0;
    }
}

Image Accumulator::image(bool aovs) const {
    Image img(width_, height_);
    for (size_t i = 0; i < pixels_.size(); ++i) {
        double rgb[3];
        mean(i, rgb);
        for (int c = 0; c < 3; ++c) img.rgb[3 * i + c] = float(rgb[c]);
    }
    if (aovs) {
        Image::Channel spp{kSampleCountChannel, std::vector<float>(pixels_.size())};
        Image::Channel variance{kVarianceChannel, std::vector<float>(pixels_.size())};
        for (size_t i = 0; i < pixels_.size(); ++i) {
            spp.values[i] = float(pixels_[i].samples);
            variance.values[i] =
                pixels_[i].samples
                    ? float(luminance_variance(i) / double(pixels_[i].samples))
                    : 0.0f;
        }
        img.extra.push_back(std::move(spp));
        img.extra.push_back(std::move(variance));
    }
    return img;
}

}  // namespace aliquot
