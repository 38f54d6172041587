#include "denoised_strategy.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "allocation.h"
#include "aux_sums.h"
#include "bands.h"
#include "optimal_strategy.h"

// Why the difference of the two denoised halves. Rousselle, Manzi and Zwicker, "Adaptive
// Rendering with Non-Local Means Filtering" (SIGGRAPH Asia 2012, Sec. 5), split the
// samples into two buffers, filter each, and take the squared difference of the two
// filtered buffers as the variance the filter left: the halves are independent, so for
// a filter that treats them alike E[(Da - Db)^2] = Var[Da] + Var[Db] = 2 Var[D(half)],
// and with each half holding half the samples, Var[D(full)] ~ Var[D(half)] / 2, so
// Var[D(full)] ~ (Da - Db)^2 / 4. It is what Cycles' half-buffer error is for the raw
// image, measured after the denoiser. One pixel's squared difference is a sample of a
// variance with three degrees of freedom (RGB), too noisy to steer by alone; the
// denoised error is spatially smooth anyway (the denoiser spreads every sample over its
// footprint), so it is pooled over a (2r+1)^2 window, as Cycles smooths its raw error (a
// 3x3 dilation). By the window's median, not its mean: a mean spreads the light's edge,
// whose denoised halves differ by hundreds of times the ceiling's, over every pixel
// around it, and the rounds then chased the light (held-out seeds 6-8 at 64x64, both
// scenes, both budgets of studies/denoised-allocation.json: the median's denoised E was
// 3-9 % below the mean's, and below no pooling's on all 4; docs/RESULTS.md). Where the
// noise is alike across the window the median is a fixed share of the mean (0.45 to 0.79
// of it, as R, G and B go from moving together to independent); the weights and the
// floor are relative, so it is not scaled back.
//
// Why n ∝ (n Var[D])^(1/3). Where the allocation is locally even over the denoiser's
// footprint, the denoised variance at a pixel falls as 1/n there: Var[D_i] = s_i^2 / n_i
// with s_i = sqrt(n_i Var[D_i]), one sample's standard deviation as seen through the
// denoiser. Minimising the mean absolute error sum_i s_i / sqrt(n_i) under sum n_i = B
// gives n_i ∝ s_i^(2/3), optimal's rule (optimal_strategy.cpp) with s in place of the raw
// sigma: pixels whose noise the denoiser removes (flat, well-guided) weigh little, those
// it cannot (caustics, fine texture with no guide) weigh much. The rounds re-estimate s
// from everything merged, so an allocation that is not locally even is corrected by the
// next round's measurement.

namespace aliquot {

namespace {

// A pixel's weight is never taken below this share of the image's median denoised
// variance: a pixel that the two denoised halves happen to agree on still gets a little
// and is measured again, as optimal's kImageFactor.
constexpr double kImageFactor = 1.0 / 256;

// The window the denoised variance is pooled over: 5x5, 25 pixels' estimates instead of
// one, about OIDN's smallest footprint on a noisy image (its receptive field is far
// wider, so the error it leaves varies slowly from pixel to pixel).
constexpr uint32_t kPoolRadius = 2;

// Open Image Denoise's working memory for one RT filter (HDR, high quality, colour,
// albedo and normal, CPU device), which its manual leaves "unspecified" and
// "device-dependent": the peak RSS one denoise added, OIDN 2.5.1 (pyoidn's library) on
// this 2-core EPYC: 42 MiB at 256x256, 150 at 512x512, 582 at 1024x1024, 1153 at
// 1920x1080, 2310 at 2048x2048 (578-583 bytes a pixel from a million pixels on, 6 MiB
// besides), and 2514 at 4096x2048, where OIDN denoises in tiles to keep its scratch
// under its default limit (maxMemoryMB, about 3000 MB since OIDN 1.4). Filters of one
// device run one at a time (the Denoiser's mutex), so a render's two passes, and
// several renders' round ends, never hold it twice at once; each render counts it all
// the same, as it is the budget's one place to ask.
constexpr uint64_t kOidnBytesPerPixel = 600;
constexpr uint64_t kOidnLargest = uint64_t(3000) << 20;
constexpr uint64_t kOidnFixed = uint64_t(16) << 20;

// The half images: the means of each pixel's even-index and odd-index samples. A pixel
// with fewer than two samples has one half only; both get its mean.
// Images of the right size are written over: every value is, so nothing carries over.
void half_images(const Accumulator& merged, Image& even, Image& odd) {
    const size_t n = merged.pixel_count();
    for (Image* half : {&even, &odd})
        if (half->width != merged.width() || half->height != merged.height() ||
            half->rgb.size() != 3 * n)
            *half = Image(merged.width(), merged.height());
    for_each_band(n, kBandPixels, [&](size_t, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            double e[3], o[3];
            if (merged.samples(i) >= 2) {
                merged.half_means(i, e, o);
            } else {
                merged.mean(i, e);
                std::copy(e, e + 3, o);
            }
            for (int c = 0; c < 3; ++c) {
                even.rgb[3 * i + c] = float(e[c]);
                odd.rgb[3 * i + c] = float(o[c]);
            }
        }
    });
}

// The median of v over the (2r+1)^2 window around each pixel, clipped at the edges; in
// bands of rows on the pool's threads, each pixel's value its window's alone, so the
// result does not depend on the threads.
std::vector<double> window_median(const std::vector<double>& v, uint32_t w, uint32_t h,
                                  uint32_t r) {
    std::vector<double> out(v.size());
    const size_t rows = std::max<size_t>(1, kBandPixels / std::max(w, 1u));
    for_each_band(h, rows, [&](size_t, size_t row0, size_t row1) {
        std::vector<double> window;
        for (uint32_t y = uint32_t(row0); y < row1; ++y)
            for (uint32_t x = 0; x < w; ++x) {
                window.clear();
                for (uint32_t yy = y > r ? y - r : 0; yy < std::min(h, y + r + 1); ++yy)
                    for (uint32_t xx = x > r ? x - r : 0; xx < std::min(w, x + r + 1);
                         ++xx)
                        window.push_back(v[size_t(yy) * w + xx]);
                std::nth_element(window.begin(), window.begin() + window.size() / 2,
                                 window.end());
                out[size_t(y) * w + x] = window[window.size() / 2];
            }
    });
    return out;
}

}  // namespace

DenoisedStrategy::DenoisedStrategy(const StrategyParams& p, uint32_t width,
                                   uint32_t height, DenoiseFunction denoise,
                                   std::shared_ptr<std::atomic<bool>> stop)
    : width_(width),
      height_(height),
      budget_(sample_budget(p, size_t(width) * height)),
      cap_(spp_cap(p)),
      steer_rounds_(std::max<uint32_t>(p.steer_rounds, 1)),
      denoise_(std::move(denoise)),
      stop_(std::move(stop)) {
    if (!denoise_) throw std::invalid_argument("method 'denoised' needs a denoiser");
    const size_t pixels = std::max<size_t>(size_t(width) * height, 1);
    // optimal's floor tied to the budget: a share of the mean spp, never below min_spp,
    // so the denoised halves the first plan reads are not the denoiser's worst case.
    const double floor = std::floor(p.floor_fraction * double(budget_) / double(pixels));
    min_spp_ = std::min<uint32_t>(
        std::max<uint32_t>(p.min_spp, uint32_t(std::min(double(UINT32_MAX), floor))),
        cap_);
    pilot_spp_ = std::min<uint64_t>({min_spp_, budget_ / pixels, cap_});
}

uint64_t DenoisedStrategy::round_end_memory(uint64_t pixels) {
    const uint64_t per_pixel =
        4 * 12    // kept: the half images and the guides (RGB floats)
        + 8       // kept: each pixel's samples
        + 2 * 12  // both denoised halves
        + 12      // the denoiser's finite copy of a colour with NaN or negatives
        + 4 * 8   // the variance, its window median, the sorted copy, sigma
        + 2 * 8   // the weights and the gaps (optimal_counts)
        + 2 * 4   // the room and the round's counts
        + sizeof(RemainderKey);  // apportion's order of the remainders
    return pixels * per_pixel + std::min(pixels * kOidnBytesPerPixel, kOidnLargest) +
           kOidnFixed;
}

void DenoisedStrategy::read_round_end(const Accumulator& merged,
                                      const AuxSums* first_hits, RoundEndCopy& copy) {
    const size_t n = merged.pixel_count();
    half_images(merged, copy.even, copy.odd);
    // Both halves are denoised with the guides of all samples: the guides' own noise
    // (edges, textures) is small, and the same guides keep the two halves' filters alike,
    // which the difference assumes.
    if (first_hits && first_hits->kept()) {
        copy.albedo = first_hits->albedo(merged);
        copy.normal = first_hits->normal(merged);
    } else {
        copy.albedo = Image();
        copy.normal = Image();
    }
    copy.samples.resize(n);
    for_each_band(n, kBandPixels, [&](size_t, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) copy.samples[i] = merged.samples(i);
    });
    copy.spent = double(merged.total_samples());
}

std::vector<double> DenoisedStrategy::denoised_sigma(const Accumulator& merged,
                                                     const AuxSums* first_hits,
                                                     const DenoiseFunction& denoise,
                                                     uint32_t radius) {
    RoundEndCopy copy;
    read_round_end(merged, first_hits, copy);
    return denoised_sigma(copy, denoise, radius);
}

std::vector<double> DenoisedStrategy::denoised_sigma(const RoundEndCopy& copy,
                                                     const DenoiseFunction& denoise,
                                                     uint32_t radius) {
    const uint32_t w = copy.even.width, h = copy.even.height;
    const size_t n = copy.samples.size();
    const Image* a = copy.albedo.rgb.empty() ? nullptr : &copy.albedo;
    const Image* nm = copy.normal.rgb.empty() ? nullptr : &copy.normal;
    const std::vector<float> de = denoise(copy.even, a, nm).rgb;
    const std::vector<float> dodd = denoise(copy.odd, a, nm).rgb;
    if (de.size() != 3 * n || dodd.size() != 3 * n)
        throw std::runtime_error("the denoiser returned an image of another size");
    // (Da - Db)^2 / 4 per channel, averaged over RGB: the denoised full image's variance.
    std::vector<double> variance(n);
    for_each_band(n, kBandPixels, [&](size_t, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            double v = 0;
            for (int c = 0; c < 3; ++c) {
                const double d = double(de[3 * i + c]) - double(dodd[3 * i + c]);
                v += d * d;
            }
            variance[i] = std::isfinite(v) ? v / 12 : 0.0;
        }
    });
    variance = window_median(variance, w, h, radius);
    std::vector<double> sorted = variance;
    std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
    const double least = n ? kImageFactor * sorted[n / 2] : 0.0;
    std::vector<double> sigma(n);
    for (size_t i = 0; i < n; ++i)
        sigma[i] = std::sqrt(std::max(variance[i], least) * double(copy.samples[i]));
    return sigma;
}

std::vector<uint32_t> DenoisedStrategy::steered_round() const {
    const RoundEndCopy& copy = round_end_;
    const size_t pixels = copy.samples.size();
    const double spent = copy.spent;
    const double remaining = double(budget_) - spent;
    if (!(remaining >= 1)) return {};
    // optimal's steered rounds: each at most what was spent before it and at most half
    // of what is left, the steer_rounds-th all of it, so the estimates behind a round
    // rest on at least half of the render so far.
    const uint32_t steered = rounds_ > 1 ? rounds_ - 1 : 0;  // the pilot is round 0
    double share = std::min(remaining, std::max(spent, 1.0));
    share = steered + 1 < steer_rounds_
                ? std::min(share, std::max(1.0, std::floor(remaining / 2)))
                : remaining;
    const std::vector<double> sigma = denoised_sigma(copy, denoise_, kPoolRadius);
    std::vector<double> weight(pixels);
    bool noise_seen = false;
    for (size_t i = 0; i < pixels; ++i) {
        weight[i] = std::cbrt(sigma[i] * sigma[i]);
        noise_seen |= weight[i] > 0;
    }
    if (!noise_seen) std::fill(weight.begin(), weight.end(), 1.0);
    // The target of every pixel after this round; the round closes the gaps to it.
    std::vector<double> gap = OptimalStrategy::optimal_counts(
        weight, {}, spent + share, double(min_spp_), double(cap_));
    std::vector<uint32_t> room(pixels);
    for (size_t i = 0; i < pixels; ++i) {
        const uint64_t have = copy.samples[i];
        gap[i] = std::max(0.0, gap[i] - double(have));
        room[i] = have < cap_ ? uint32_t(cap_ - have) : 0;
    }
    return apportion(gap, share, room);
}

// Off the lock. A round end of `denoised` is two OIDN passes over the whole image (0.1 s
// at 128x128, minutes at 8192x8192 on 2 cores): under the render's lock it held up
// every lease scan that reached the render and the results of its own. Nothing is out
// while it runs (each plan needs everything merged before it, so no round is planned
// ahead), but the render's lock is free: the copy is one pass over the buffers, and the
// plan from it is the plan next_round makes in place, the same bits.
std::function<void()> DenoisedStrategy::take_round_end(const Accumulator& merged) {
    // The pilot needs no plan, and a spent budget ends the render in next_round.
    if (finished_ || rounds_ == 0 || round_end_read_ ||
        !(double(budget_) - double(merged.total_samples()) >= 1))
        return {};
    read_round_end(merged, first_hits_, round_end_);
    round_end_read_ = true;
    planned_.reset();
    return [this] { planned_ = steered_round(); };
}

std::optional<Round> DenoisedStrategy::next_round(const Accumulator& merged) {
    if (finished_) return std::nullopt;
    const size_t pixels = size_t(width_) * height_;
    Round round{rounds_, {}};
    if (rounds_ == 0) {
        if (pilot_spp_ > 0) {
            round.spp.assign(pixels, uint32_t(pilot_spp_));
        } else {
            // Less than a sample per pixel: nothing can be estimated, so the budget is
            // spread evenly in one round, as optimal does.
            finished_ = true;
            round.spp = apportion(std::vector<double>(pixels, 1.0), double(budget_),
                                  std::vector<uint32_t>(pixels, cap_));
        }
    } else {
        // Read here unless take_round_end did; planned here unless its work ran.
        if (!round_end_read_) read_round_end(merged, first_hits_, round_end_);
        round.spp = planned_ ? std::move(*planned_) : steered_round();
        planned_.reset();
        round_end_read_ = false;
    }
    const uint64_t total = round.total();
    if (total == 0) {
        finished_ = true;
        return std::nullopt;
    }
    issued_ += total;
    ++rounds_;
    return round;
}

nlohmann::json DenoisedStrategy::outcome() const {
    return {{"budget", budget_},
            {"samples", issued_},
            {"rounds", rounds_},
            {"unspent", budget_ > issued_ ? budget_ - issued_ : 0}};
}

nlohmann::json DenoisedStrategy::save_state() const {
    return {{"rounds", rounds_}, {"issued", issued_}, {"finished", finished_}};
}

void DenoisedStrategy::restore_state(const nlohmann::json& state) {
    rounds_ = state.at("rounds").get<uint32_t>();
    issued_ = state.at("issued").get<uint64_t>();
    finished_ = state.at("finished").get<bool>();
    round_end_read_ = false;
    planned_.reset();
}

}  // namespace aliquot
