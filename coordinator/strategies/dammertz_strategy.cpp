#include "dammertz_strategy.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "allocation.h"
#include "bands.h"

namespace aliquot {

namespace {

// The seed saw pixels that needed 80,000 samples to reach its V; the default caps stop
// well before an unreachable V can run for ever while leaving such pixels most of that.
constexpr uint32_t kDefaultMaxSpp = 65536;
constexpr uint64_t kDefaultMaxSamplesPerPixel = 4096;
// The paper's norm divides by sqrt(sum_c I); a black pixel has I = 0 (and so |I - A| =
// 0). Flooring sum_c I bounds the gain a nearly black pixel can give its error at 1e4.
constexpr double kPaperNormFloor = 1e-8;

// Leaves in one band of a pass over leaves: a few, as most are small late in a render.
constexpr size_t kLeavesPerBand = 16;

uint64_t saturating_mul(uint64_t a, uint64_t b) {
    return (a && b > std::numeric_limits<uint64_t>::max() / a)
               ? std::numeric_limits<uint64_t>::max()
               : a * b;
}

const char* state_name(DammertzStrategy::State s) {
    switch (s) {
        case DammertzStrategy::State::active:
            return "active";
        case DammertzStrategy::State::converged:
            return "converged";
        case DammertzStrategy::State::capped:
            return "capped";
    }
    return "active";
}

DammertzStrategy::State parse_state(const std::string& s) {
    if (s == "active") return DammertzStrategy::State::active;
    if (s == "converged") return DammertzStrategy::State::converged;
    if (s == "capped") return DammertzStrategy::State::capped;
    throw std::invalid_argument("dammertz state: unknown bucket state '" + s + "'");
}

size_t top_left(const PixelRect& r, uint32_t width) { return size_t(r.y) * width + r.x; }

}  // namespace

DammertzStrategy::DammertzStrategy(const StrategyParams& p, uint32_t width,
                                   uint32_t height)
    : width_(width),
      height_(height),
      max_variance_(p.max_variance),
      samples_per_iteration_(p.samples_per_iteration),
      split_factor_(p.split_factor),
      min_bucket_size_(std::max<uint32_t>(p.min_bucket_size, 1)),
      paper_norm_(p.error_norm == "paper"),
      max_spp_(p.max_spp ? p.max_spp : kDefaultMaxSpp) {
    const uint64_t pixels = uint64_t(width) * height;
    // Dammertz does not aim at a budget; one given is a cap on what it may spend.
    if (p.budget || p.spp)
        max_samples_ = sample_budget(p, pixels);
    else if (p.max_samples)
        max_samples_ = p.max_samples;
    else
        max_samples_ = saturating_mul(kDefaultMaxSamplesPerPixel, pixels);
    leaves_.push_back({{0, 0, width, height}, State::active, 0});
}

uint64_t DammertzStrategy::planned_samples() const {
    return std::min(max_samples_, saturating_mul(max_spp_, uint64_t(width_) * height_));
}

double DammertzStrategy::pixel_error(const Accumulator& merged, size_t i) const {
    // The seed's norm below, kept by the accumulator as results merge (the same
    // operations, so the same bits): 8 bytes a pixel to read.
    if (!paper_norm_ && merged.half_difference(i) >= 0) return merged.half_difference(i);
    double even[3], odd[3];
    merged.half_means(i, even, odd);
    double e = 0;
    if (paper_norm_) {
        // Paper: |I - A| over the channels, I the full mean and A the even half,
        // normalised by sqrt(sum_c I) as a stand-in for the eye's response.
        double full[3];
        merged.mean(i, full);
        double diff = 0, sum = 0;
        for (int c = 0; c < 3; ++c) {
            diff += std::abs(full[c] - even[c]);
            sum += full[c];
        }
        e = diff / std::sqrt(std::max(sum, kPaperNormFloor));
    } else {
        // Seed: the mean absolute difference of the two half images, over RGB.
        for (int c = 0; c < 3; ++c) e += std::abs(even[c] - odd[c]);
        e /= 3;
    }
    return e;
}

std::vector<double> DammertzStrategy::pixel_errors(const Accumulator& merged,
                                                   const PixelRect& rect) const {
    std::vector<double> errors(rect.size());
    // Each pixel's error on its own, in bands of rows on the pool's threads (bands.h);
    // inside another pass (evaluate's, over leaves) on this thread.
    const size_t band_rows = std::max<size_t>(1, kBandPixels / std::max(rect.width, 1u));
    for_each_band(rect.height, band_rows, [&](size_t, size_t row0, size_t row1) {
        for (uint32_t row = uint32_t(row0); row < row1; ++row)
            for (uint32_t col = 0; col < rect.width; ++col)
                errors[size_t(row) * rect.width + col] =
                    pixel_error(merged, size_t(rect.y + row) * width_ + rect.x + col);
    });
    return errors;
}

double DammertzStrategy::error_sum(const Accumulator& merged,
                                   const PixelRect& rect) const {
    // Row-major, one pixel after another: bucket_error's sum of pixel_errors, the same
    // additions in the same order.
    double sum = 0;
    for (uint32_t y = rect.y; y < rect.y + rect.height; ++y)
        for (uint32_t x = rect.x; x < rect.x + rect.width; ++x)
            sum += pixel_error(merged, size_t(y) * width_ + x);
    return sum;
}

double DammertzStrategy::bucket_error(const std::vector<double>& errors) const {
    double sum = 0;
    for (double e : errors) sum += e;
    return bucket_error(sum, errors.size());
}

double DammertzStrategy::bucket_error(double sum, size_t pixels) const {
    if (pixels == 0) return 0;
    const double mean = sum / double(pixels);
    if (!paper_norm_) return mean;
    // The paper's area factor sqrt(N_b / N): a small bucket's error weighs less, so the
    // tree does not chase noise into single pixels.
    return mean * std::sqrt(double(pixels) / (double(width_) * height_));
}

double DammertzStrategy::part_error(const std::vector<double>& errors,
                                    const PixelRect& rect, const PixelRect& part) const {
    // Row-major over the part, as bucket_error(pixel_errors(merged, part)) sums them.
    double sum = 0;
    for (uint32_t y = part.y; y < part.y + part.height; ++y) {
        const double* row = &errors[size_t(y - rect.y) * rect.width + (part.x - rect.x)];
        for (uint32_t x = 0; x < part.width; ++x) sum += row[x];
    }
    return bucket_error(sum, part.size());
}

std::optional<std::pair<PixelRect, PixelRect>> DammertzStrategy::split(
    const PixelRect& rect, const std::vector<double>& errors, uint32_t min_size) {
    const bool along_x = rect.width >= rect.height;  // a square bucket is cut vertically
    const uint32_t length = along_x ? rect.width : rect.height;
    min_size = std::max<uint32_t>(min_size, 1);
    if (length < 2 * uint64_t(min_size)) return std::nullopt;

    std::vector<double> prefix(length + 1, 0.0);  // error before line s
    {
        std::vector<double> line(length, 0.0);
        for (uint32_t row = 0; row < rect.height; ++row)
            for (uint32_t col = 0; col < rect.width; ++col)
                line[along_x ? col : row] += errors[size_t(row) * rect.width + col];
        for (uint32_t s = 0; s < length; ++s) prefix[s + 1] = prefix[s] + line[s];
    }
    const double total = prefix[length];
    uint32_t best = min_size;
    double best_gap = std::numeric_limits<double>::infinity();
    int64_t best_off_centre = std::numeric_limits<int64_t>::max();
    for (uint32_t s = min_size; s <= length - min_size; ++s) {
        // Ties (e.g. no error at all on a stretch) go to the cut nearest the middle.
        const double gap = std::abs(2 * prefix[s] - total);
        const int64_t off_centre = std::abs(2 * int64_t(s) - int64_t(length));
        if (gap < best_gap || (gap == best_gap && off_centre < best_off_centre)) {
            best = s;
            best_gap = gap;
            best_off_centre = off_centre;
        }
    }
    PixelRect first = rect, second = rect;
    if (along_x) {
        first.width = best;
        second.x += best;
        second.width -= best;
    } else {
        first.height = best;
        second.y += best;
        second.height -= best;
    }
    return std::make_pair(first, second);
}

DammertzStrategy::Judged DammertzStrategy::judge(const Accumulator& merged,
                                                 Leaf leaf) const {
    // The halves need a sample each before they can be compared.
    if (leaf.state != State::active || merged.samples(top_left(leaf.rect, width_)) < 2)
        return {leaf, std::nullopt};
    // The pixels' errors are kept, a vector of the leaf's size, only where a split may
    // need them: a leaf whose E was far above split_factor V a round ago is judged from
    // the errors summed as they are read (a leaf of 1920x1080 was 16 MB written and read
    // again every round). Either way E is the same sum, in the same order.
    std::vector<double> errors;
    if (leaf.error <= 2 * split_factor_ * max_variance_) {
        errors = pixel_errors(merged, leaf.rect);
        leaf.error = bucket_error(errors);
    } else {
        leaf.error = bucket_error(error_sum(merged, leaf.rect), leaf.rect.size());
    }
    if (leaf.error <= max_variance_) {
        leaf.state = State::converged;
    } else if (leaf.error <= split_factor_ * max_variance_) {
        if (errors.empty()) errors = pixel_errors(merged, leaf.rect);
        if (auto halves = split(leaf.rect, errors, min_bucket_size_)) {
            // Each half's E from the leaf's errors: the pixels' own, read once.
            return {Leaf{halves->first, State::active,
                         part_error(errors, leaf.rect, halves->first)},
                    Leaf{halves->second, State::active,
                         part_error(errors, leaf.rect, halves->second)}};
        }
        // Too small to split: it keeps sampling as a whole.
    }
    return {leaf, std::nullopt};
}

void DammertzStrategy::evaluate(const Accumulator& merged) {
    // Each leaf is judged on its own, into its own slot, and the tree put together in
    // the leaves' order: the same tree whatever the threads. Large leaves one after
    // another, each in bands of rows (the first leaf is the whole image); the others in
    // bands of leaves.
    std::vector<Judged> judged(leaves_.size());
    std::vector<size_t> small;
    for (size_t l = 0; l < leaves_.size(); ++l) {
        if (leaves_[l].rect.size() >= kBandPixels)
            judged[l] = judge(merged, leaves_[l]);
        else
            small.push_back(l);
    }
    for_each_band(small.size(), kLeavesPerBand, [&](size_t, size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k)
            judged[small[k]] = judge(merged, leaves_[small[k]]);
    });
    std::vector<Leaf> next;
    next.reserve(leaves_.size() + 8);
    for (const Judged& j : judged) {
        next.push_back(j.first);
        if (j.second) next.push_back(*j.second);
    }
    leaves_ = std::move(next);
}

std::optional<Round> DammertzStrategy::next_round(const Accumulator& merged) {
    if (finished_) return std::nullopt;
    if (evaluate_pending_) {
        evaluate(merged);
        evaluate_pending_ = false;
    }
    // Every pixel of a leaf has had the same samples (its ancestors were sampled whole),
    // so the top-left pixel speaks for the leaf.
    std::vector<std::pair<size_t, uint32_t>> plan;  // leaf, samples per pixel
    uint64_t total = 0, active_pixels = 0;
    for (size_t l = 0; l < leaves_.size(); ++l) {
        Leaf& leaf = leaves_[l];
        if (leaf.state != State::active) continue;
        const uint64_t have = merged.samples(top_left(leaf.rect, width_));
        if (have >= max_spp_) {
            leaf.state = State::capped;
            continue;
        }
        const uint32_t s =
            uint32_t(std::min<uint64_t>(samples_per_iteration_, max_spp_ - have));
        plan.emplace_back(l, s);
        total += uint64_t(s) * leaf.rect.size();
        active_pixels += leaf.rect.size();
    }
    if (plan.empty()) {
        finished_ = true;
        return std::nullopt;
    }
    // A round that would pass max_samples shrinks to what fits, evenly over the active
    // pixels so that every leaf stays evenly sampled; when not one sample each fits,
    // stop.
    const uint64_t spent = merged.total_samples();
    const uint64_t room = max_samples_ > spent ? max_samples_ - spent : 0;
    if (total > room) {
        const uint64_t fit = room / active_pixels;
        if (fit == 0) {
            finished_ = true;
            stopped_by_max_samples_ = true;
            return std::nullopt;
        }
        for (auto& [leaf, s] : plan) s = uint32_t(std::min<uint64_t>(s, fit));
    }
    Round round{rounds_, std::vector<uint32_t>(size_t(width_) * height_, 0)};
    // The leaves do not overlap: each band of them fills its own pixels.
    for_each_band(plan.size(), kLeavesPerBand, [&](size_t, size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k) {
            const PixelRect& r = leaves_[plan[k].first].rect;
            for (uint32_t y = r.y; y < r.y + r.height; ++y)
                std::fill_n(round.spp.begin() + size_t(y) * width_ + r.x, r.width,
                            plan[k].second);
        }
    });
    ++rounds_;
    evaluate_pending_ = true;
    return round;
}

std::string DammertzStrategy::stop_reason() const {
    if (!finished_) return "running";
    if (stopped_by_max_samples_) return "max_samples";
    for (const Leaf& leaf : leaves_)
        if (leaf.state == State::capped) return "max_spp";
    return "converged";
}

std::vector<Bucket> DammertzStrategy::buckets() const {
    std::vector<Bucket> out;
    out.reserve(leaves_.size());
    for (const Leaf& leaf : leaves_)
        out.push_back({leaf.rect, leaf.error, leaf.state == State::converged});
    return out;
}

nlohmann::json DammertzStrategy::outcome() const {
    uint64_t converged_pixels = 0, unconverged_buckets = 0;
    for (const Leaf& leaf : leaves_) {
        if (leaf.state == State::converged)
            converged_pixels += leaf.rect.size();
        else
            ++unconverged_buckets;
    }
    const uint64_t pixels = uint64_t(width_) * height_;
    return {{"stopped_by", stop_reason()},
            {"converged_fraction", double(converged_pixels) / double(pixels)},
            {"unconverged_buckets", unconverged_buckets},
            {"unconverged_pixels", pixels - converged_pixels},
            {"rounds", rounds_},
            {"max_spp", max_spp_},
            {"max_samples", max_samples_}};
}

nlohmann::json DammertzStrategy::save_state() const {
    nlohmann::json leaves = nlohmann::json::array();
    for (const Leaf& leaf : leaves_)
        leaves.push_back({{"x", leaf.rect.x},
                          {"y", leaf.rect.y},
                          {"width", leaf.rect.width},
                          {"height", leaf.rect.height},
                          {"state", state_name(leaf.state)},
                          {"error", leaf.error}});
    return {{"leaves", leaves},
            {"rounds", rounds_},
            {"evaluate_pending", evaluate_pending_},
            {"finished", finished_},
            {"stopped_by_max_samples", stopped_by_max_samples_}};
}

void DammertzStrategy::restore_state(const nlohmann::json& state) {
    std::vector<Leaf> leaves;
    uint64_t area = 0;
    for (const auto& l : state.at("leaves")) {
        Leaf leaf{{l.at("x").get<uint32_t>(), l.at("y").get<uint32_t>(),
                   l.at("width").get<uint32_t>(), l.at("height").get<uint32_t>()},
                  parse_state(l.at("state").get<std::string>()),
                  l.at("error").get<double>()};
        const PixelRect& r = leaf.rect;
        if (r.size() == 0 || uint64_t(r.x) + r.width > width_ ||
            uint64_t(r.y) + r.height > height_)
            throw std::invalid_argument(
                "dammertz state: a bucket lies outside the image");
        area += r.size();
        leaves.push_back(leaf);
    }
    if (area != uint64_t(width_) * height_)
        throw std::invalid_argument("dammertz state: buckets do not cover the image");
    leaves_ = std::move(leaves);
    rounds_ = state.at("rounds").get<uint32_t>();
    evaluate_pending_ = state.at("evaluate_pending").get<bool>();
    finished_ = state.at("finished").get<bool>();
    stopped_by_max_samples_ = state.at("stopped_by_max_samples").get<bool>();
}

}  // namespace aliquot
