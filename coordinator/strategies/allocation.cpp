#include "allocation.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <new>
#include <utility>

#include "bands.h"
#include "sampler.h"

namespace aliquot {

namespace {

// A per-item buffer whose every element is written before it is read: built without the
// zero fill std::vector gives, which at 1920x1080 was ~90 MB of memset at a round's end
// on top of the kernel's zeroing of the same fresh pages.
template <typename T>
struct NoZeroFill : std::allocator<T> {
    template <typename U>
    struct rebind {
        using other = NoZeroFill<U>;
    };
    NoZeroFill() = default;
    template <typename U>
    NoZeroFill(const NoZeroFill<U>&) noexcept {}
    template <typename U>
    void construct(U* p) noexcept {
        ::new (static_cast<void*>(p)) U;  // default-initialised: left as it is
    }
    template <typename U, typename... Args>
    void construct(U* p, Args&&... args) {
        ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
};
template <typename T>
using Scratch = std::vector<T, NoZeroFill<T>>;

// The real-valued shares: item i gets min(lambda * w_i, cap_i) with one lambda for all,
// chosen so the costs add up to `total`. The items that reach their cap are those with
// the smallest cap_i / w_i, so walking them in that order finds lambda exactly.
// Only the shares of the items in `order` are written, and only they are read after.
template <typename Cost>
Scratch<double> water_fill(const Scratch<size_t>& order,
                           const std::vector<double>& weights,
                           const std::vector<uint32_t>& caps, double total,
                           const Cost& cost) {
    Scratch<double> share(weights.size());
    double all = 0;  // summed in order on one thread: the same bits as ever
    for (size_t i : order) all += cost(i) * weights[i];
    const double first = all > 0 ? total / all : 0.0;
    std::vector<char> band_capped(band_count(order.size(), kBandPixels), 0);
    for_each_band(order.size(), kBandPixels, [&](size_t band, size_t begin, size_t end) {
        bool capped = false;
        for (size_t k = begin; k < end; ++k)
            capped = capped || first * weights[order[k]] >= caps[order[k]];
        band_capped[band] = capped;
    });
    const bool any_capped =
        std::find(band_capped.begin(), band_capped.end(), 1) != band_capped.end();
    if (!any_capped) {  // the usual case: no cap binds, no sorting needed
        for_each_band(order.size(), kBandPixels, [&](size_t, size_t begin, size_t end) {
            for (size_t k = begin; k < end; ++k)
                share[order[k]] = first * weights[order[k]];
        });
        return share;
    }
    std::vector<std::pair<double, size_t>> by_ratio;
    by_ratio.reserve(order.size());
    for (size_t i : order) by_ratio.emplace_back(caps[i] / weights[i], i);
    std::sort(by_ratio.begin(), by_ratio.end());
    Scratch<size_t> ranked(order.size());  // the items, first to reach their caps first
    for (size_t k = 0; k < ranked.size(); ++k) ranked[k] = by_ratio[k].second;
    std::vector<double> suffix(ranked.size() + 1, 0.0);  // sum of cost * weight from k on
    for (size_t k = ranked.size(); k-- > 0;)
        suffix[k] = suffix[k + 1] + cost(ranked[k]) * weights[ranked[k]];
    double left = total;
    size_t k = 0;
    for (; k < ranked.size(); ++k) {
        const size_t i = ranked[k];
        if (!(suffix[k] > 0) || left / suffix[k] * weights[i] < caps[i]) break;
        share[i] = caps[i];
        left -= cost(i) * caps[i];
    }
    const double lambda =
        (k < ranked.size() && suffix[k] > 0 && left > 0) ? left / suffix[k] : 0;
    for (; k < ranked.size(); ++k) {
        const size_t i = ranked[k];
        share[i] = std::min(lambda * weights[i], double(caps[i]));
    }
    return share;
}

// Order in which items receive the remainder: largest fractional part first, ties by a
// hash of the index (so equal shares are spread over the image), then by the index.
struct RemainderKey {
    double fraction;
    uint64_t hash;
    size_t index;
    bool operator<(const RemainderKey& o) const {
        if (fraction != o.fraction) return fraction > o.fraction;
        return hash != o.hash ? hash < o.hash : index < o.index;
    }
};

// The indices i < n with keep(i), ascending; found in bands.
template <typename Keep>
Scratch<size_t> in_order(size_t n, const Keep& keep) {
    const size_t bands = band_count(n, kBandPixels);
    std::vector<size_t> offset(bands + 1, 0);
    for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        size_t m = 0;
        for (size_t i = begin; i < end; ++i) m += keep(i) ? 1 : 0;
        offset[band + 1] = m;
    });
    for (size_t b = 0; b < bands; ++b) offset[b + 1] += offset[b];
    Scratch<size_t> order(offset[bands]);
    for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        size_t k = offset[band];
        for (size_t i = begin; i < end; ++i)
            if (keep(i)) order[k++] = i;
    });
    return order;
}

// A remainder fraction's bucket: floor(fraction * kFractionBuckets), which never falls
// as the fraction rises, so the buckets are in the fractions' order. Fractions lie in
// [0, 1) and spread evenly over it, so each bucket holds about as many keys (~120 at
// 1920x1080); bucketing by the top bits of their bit patterns put half of them, those
// in [0.5, 1), into 16 buckets, whose sorts were most of optimal-time's round end.
constexpr size_t kFractionBuckets = size_t(1) << 14;
size_t fraction_bucket(double fraction) {
    // (Multiplying by a power of two is exact; a NaN, which no share gives, goes first.)
    return fraction > 0 ? std::min(kFractionBuckets - 1,
                                   size_t(fraction * double(kFractionBuckets)))
                        : 0;
}

// For each band of keys, how many of its keys fall in each of `buckets` buckets.
template <typename Count>
std::vector<std::vector<Count>> bucket_counts(const Scratch<RemainderKey>& keys,
                                              size_t buckets) {
    std::vector<std::vector<Count>> counts(band_count(keys.size(), kBandPixels));
    for_each_band(keys.size(), kBandPixels, [&](size_t band, size_t begin, size_t end) {
        std::vector<Count>& h = counts[band];
        h.assign(buckets, 0);
        for (size_t k = begin; k < end; ++k) ++h[fraction_bucket(keys[k].fraction)];
    });
    return counts;
}

// Gives one more unit to each of the n first keys in RemainderKey's order (below its
// cap) and returns how many it gave. The order is total (the index breaks ties), so
// those n are one set, however they are found: here, a histogram of the fractions'
// buckets (fraction_bucket), counted in bands, finds the bucket the n-th key falls in;
// every key in a larger bucket is taken, and selection runs only on that bucket
// (nth_element on all the keys was most of apportion's time). The keys are left in
// some other order: no caller depends on theirs, and reordering them in place spares a
// copy of the bucket, which for a method whose shares are all alike (adaptive's flat
// buckets) is nearly all of them: 48 MB of fresh pages at 1920x1080.
size_t give_one_each(Scratch<RemainderKey>& keys, size_t n, std::vector<uint32_t>& count,
                     const std::vector<uint32_t>& caps) {
    if (n == 0) return 0;
    if (keys.size() <= kBandPixels) {  // one band: a histogram would cost more
        std::nth_element(keys.begin(), keys.begin() + n, keys.end());
        size_t given = 0;
        for (size_t k = 0; k < n; ++k)
            if (count[keys[k].index] < caps[keys[k].index]) {
                ++count[keys[k].index];
                ++given;
            }
        return given;
    }
    constexpr size_t kBuckets = kFractionBuckets;
    const std::vector<std::vector<uint32_t>> histogram =
        bucket_counts<uint32_t>(keys, kBuckets);
    const size_t bands = histogram.size();
    // Largest fractions first: the bucket holding the n-th key, and how many of it.
    size_t bucket = kBuckets, wanted = n;
    while (bucket-- > 0) {
        size_t in_bucket = 0;
        for (const std::vector<uint32_t>& h : histogram) in_bucket += h[bucket];
        if (wanted <= in_bucket) break;
        wanted -= in_bucket;
    }
    std::vector<size_t> offset(bands + 1, 0);
    for (size_t b = 0; b < bands; ++b) offset[b + 1] = offset[b] + histogram[b][bucket];
    // A small bucket is copied out in bands; a large one is gathered at the front of the
    // keys in place (one serial pass, but no new pages).
    const bool in_place = offset[bands] > keys.size() / 8;
    Scratch<RemainderKey> copied(in_place ? 0 : offset[bands]);
    std::vector<size_t> given(bands, 0);
    for_each_band(keys.size(), kBandPixels, [&](size_t band, size_t begin, size_t end) {
        size_t t = offset[band], g = 0;
        for (size_t k = begin; k < end; ++k) {
            const size_t b = fraction_bucket(keys[k].fraction);
            if (b == bucket) {
                if (!in_place) copied[t++] = keys[k];
            } else if (b > bucket && count[keys[k].index] < caps[keys[k].index]) {
                ++count[keys[k].index];
                ++g;
            }
        }
        given[band] = g;
    });
    RemainderKey* tied = copied.data();
    if (in_place) {
        std::partition(keys.begin(), keys.end(), [&](const RemainderKey& key) {
            return fraction_bucket(key.fraction) == bucket;
        });
        tied = keys.data();
    }
    std::nth_element(tied, tied + (wanted - 1), tied + offset[bands]);
    size_t total = 0;
    for (size_t g : given) total += g;
    for (size_t k = 0; k < wanted; ++k)
        if (count[tied[k].index] < caps[tied[k].index]) {
            ++count[tied[k].index];
            ++total;
        }
    return total;
}

// Sorts keys into RemainderKey's order, which is total, so the result is the one
// std::sort gives. The keys are first spread over their fractions' buckets
// (fraction_bucket; largest first), counted and scattered in bands, and each bucket is
// then sorted alone, buckets shared among the pool's threads. std::sort of all of them
// was the largest part of optimal-time's round end at 1920x1080.
void sort_keys(Scratch<RemainderKey>& keys) {
    if (keys.size() <= kBandPixels) {  // one band: a histogram would cost more
        std::sort(keys.begin(), keys.end());
        return;
    }
    constexpr size_t kBuckets = kFractionBuckets;
    // at[band][bucket]: first the band's count of that bucket, then where the band's next
    // key of that bucket goes.
    std::vector<std::vector<size_t>> at = bucket_counts<size_t>(keys, kBuckets);
    const size_t bands = at.size();
    std::vector<size_t> start(kBuckets + 1, 0);  // bucket b's first place, largest first
    size_t place = 0;
    for (size_t b = kBuckets; b-- > 0;) {
        start[b] = place;
        for (size_t band = 0; band < bands; ++band) {
            const size_t n = at[band][b];
            at[band][b] = place;
            place += n;
        }
    }
    Scratch<RemainderKey> sorted(keys.size());
    for_each_band(keys.size(), kBandPixels, [&](size_t band, size_t begin, size_t end) {
        std::vector<size_t>& next = at[band];
        for (size_t k = begin; k < end; ++k)
            sorted[next[fraction_bucket(keys[k].fraction)]++] = keys[k];
    });
    for_each_band(kBuckets, 256, [&](size_t, size_t begin, size_t end) {
        for (size_t b = begin; b < end; ++b) {
            const size_t first = start[b], last = b ? start[b - 1] : keys.size();
            std::sort(sorted.begin() + first, sorted.begin() + last);
        }
    });
    keys.swap(sorted);
}

}  // namespace

std::vector<uint32_t> apportion(const std::vector<double>& weights, double total,
                                const std::vector<uint32_t>& caps,
                                const std::vector<double>& costs) {
    const bool unit = costs.empty();
    auto cost = [&](size_t i) { return unit ? 1.0 : costs[i]; };
    if (unit) total = std::floor(total);
    std::vector<uint32_t> count(weights.size(), 0);
    if (!(total > 0)) return count;

    // The passes over every item run in bands on the pool's threads (bands.h); what is
    // summed in floating point is summed in order on this one, so the counts are the
    // same whatever the threads.
    const Scratch<size_t> order =
        in_order(weights.size(), [&](size_t i) { return weights[i] > 0 && caps[i] > 0; });
    const Scratch<double> share = water_fill(order, weights, caps, total, cost);

    const size_t bands = band_count(order.size(), kBandPixels);
    std::vector<uint64_t> band_floors(bands, 0);
    Scratch<RemainderKey> keys(order.size());
    for_each_band(order.size(), kBandPixels, [&](size_t band, size_t begin, size_t end) {
        uint64_t floors = 0;
        for (size_t k = begin; k < end; ++k) {
            const size_t i = order[k];
            count[i] = uint32_t(std::min(std::floor(share[i]), double(caps[i])));
            floors += count[i];
            keys[k] = {share[i] - std::floor(share[i]), mix64(i), i};
        }
        band_floors[band] = floors;
    });
    double left = total;
    if (unit) {
        // Whole numbers far below 2^53: the difference is exact, as the running
        // subtraction was.
        uint64_t floors = 0;
        for (uint64_t f : band_floors) floors += f;
        left = total - double(floors);
    } else {
        for (size_t i : order) left -= cost(i) * count[i];
    }
    if (unit && left >= 0 && left < double(keys.size())) {
        // The usual case: one more unit each for the `left` largest fractional parts.
        // None of them is at its cap (a capped item has fraction 0 and sorts last among
        // them).
        left -= double(give_one_each(keys, size_t(left), count, caps));
    }
    if (left == 0) return count;
    sort_keys(keys);
    // Rounding can leave the floors a unit over the total: take it back from the smallest
    // fractional parts.
    for (size_t k = keys.size(); left < 0 && k-- > 0;) {
        const size_t i = keys[k].index;
        if (count[i] > 0) {
            --count[i];
            left += cost(i);
        }
    }
    for (bool gave = true; gave && left > 0;) {
        gave = false;
        for (const RemainderKey& key : keys) {
            const size_t i = key.index;
            if (count[i] < caps[i] && cost(i) <= left) {
                ++count[i];
                left -= cost(i);
                gave = true;
                if (!(left > 0)) break;
            }
        }
    }
    return count;
}

uint64_t sample_budget(const StrategyParams& params, size_t pixels) {
    uint64_t budget = params.budget ? params.budget : params.spp * uint64_t(pixels);
    if (params.max_samples) budget = std::min(budget, params.max_samples);
    return budget;
}

}  // namespace aliquot
