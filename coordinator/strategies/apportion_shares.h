// The real-valued shares apportion (allocation.h) rounds to whole counts: each item's
// share of the total in proportion to its weight, and the water-filling that binds the
// caps. Private to allocation.cpp and the remainder order (remainder_order.h).
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <new>
#include <utility>
#include <vector>

#include "bands.h"

namespace aliquot::apportioning {

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
// chosen so the costs add up to `total`. In the usual case no cap binds and the share is
// first * w_i, computed where it is needed rather than kept (16 MB of fresh pages at
// 1920x1080); otherwise each item's share is kept in `kept`.
struct Shares {
    const std::vector<double>* weights = nullptr;
    double first = 0;
    bool capped = false;
    Scratch<double> kept;  // when capped: the shares of the items apportion considers
    double operator()(size_t i) const { return capped ? kept[i] : first * (*weights)[i]; }
};

// The shares while no cap binds: first * w_i, with the costs adding up to `total`.
// `keep(i)` says which items are considered.
template <typename Keep, typename Cost>
Shares proportional_shares(const std::vector<double>& weights, double total,
                           const Keep& keep, const Cost& cost, const double* kept_total) {
    const size_t n = weights.size();
    Shares shares;
    shares.weights = &weights;
    if (kept_total) {  // summed by the caller, as below
        shares.first = *kept_total > 0 ? total / *kept_total : 0.0;
        return shares;
    }
    std::vector<double> band_all(band_count(n, kBandPixels), 0.0);
    for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
        double all = 0;
        for (size_t i = begin; i < end; ++i)
            if (keep(i)) all += cost(i) * weights[i];
        band_all[band] = all;
    });
    double all = 0;
    for (double a : band_all) all += a;
    shares.first = all > 0 ? total / all : 0.0;
    return shares;
}

// When some proportional share reaches its cap (water-filling): the items that reach it
// are those with the smallest cap_i / w_i, so walking them in that order finds lambda
// exactly.
template <typename Keep, typename Cost>
void bind_caps(Shares& shares, const std::vector<uint32_t>& caps, double total,
               const Keep& keep, const Cost& cost) {
    const std::vector<double>& weights = *shares.weights;
    const size_t n = weights.size();
    shares.capped = true;
    shares.kept.resize(n);
    std::vector<std::pair<double, size_t>> by_ratio;
    for (size_t i = 0; i < n; ++i)
        if (keep(i)) by_ratio.emplace_back(caps[i] / weights[i], i);
    std::sort(by_ratio.begin(), by_ratio.end());
    std::vector<double> suffix(by_ratio.size() + 1,
                               0.0);  // sum of cost * weight from k on
    for (size_t k = by_ratio.size(); k-- > 0;) {
        const size_t i = by_ratio[k].second;
        suffix[k] = suffix[k + 1] + cost(i) * weights[i];
    }
    double left = total;
    size_t k = 0;
    for (; k < by_ratio.size(); ++k) {
        const size_t i = by_ratio[k].second;
        if (!(suffix[k] > 0) || left / suffix[k] * weights[i] < caps[i]) break;
        shares.kept[i] = caps[i];
        left -= cost(i) * caps[i];
    }
    const double lambda =
        (k < by_ratio.size() && suffix[k] > 0 && left > 0) ? left / suffix[k] : 0;
    for (; k < by_ratio.size(); ++k) {
        const size_t i = by_ratio[k].second;
        shares.kept[i] = std::min(lambda * weights[i], double(caps[i]));
    }
}
}  // namespace aliquot::apportioning
