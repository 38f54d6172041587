#include "allocation.h"

#include <algorithm>
#include <cmath>

#include "sampler.h"

namespace aliquot {

namespace {

// The real-valued shares: item i gets min(lambda * w_i, cap_i) with one lambda for all,
// chosen so the costs add up to `total`. The items that reach their cap are those with
// the smallest cap_i / w_i, so walking them in that order finds lambda exactly.
template <typename Cost>
std::vector<double> water_fill(std::vector<size_t> order,
                               const std::vector<double>& weights,
                               const std::vector<uint32_t>& caps, double total,
                               const Cost& cost) {
    std::vector<double> share(weights.size(), 0.0);
    double all = 0;
    for (size_t i : order) all += cost(i) * weights[i];
    const double first = all > 0 ? total / all : 0.0;
    bool any_capped = false;
    for (size_t i : order) any_capped = any_capped || first * weights[i] >= caps[i];
    if (!any_capped) {  // the usual case: no cap binds, no sorting needed
        for (size_t i : order) share[i] = first * weights[i];
        return share;
    }
    std::vector<std::pair<double, size_t>> by_ratio;
    by_ratio.reserve(order.size());
    for (size_t i : order) by_ratio.emplace_back(caps[i] / weights[i], i);
    std::sort(by_ratio.begin(), by_ratio.end());
    for (size_t k = 0; k < order.size(); ++k) order[k] = by_ratio[k].second;
    std::vector<double> suffix(order.size() + 1, 0.0);  // sum of cost * weight from k on
    for (size_t k = order.size(); k-- > 0;)
        suffix[k] = suffix[k + 1] + cost(order[k]) * weights[order[k]];
    double left = total;
    size_t k = 0;
    for (; k < order.size(); ++k) {
        const size_t i = order[k];
        if (!(suffix[k] > 0) || left / suffix[k] * weights[i] < caps[i]) break;
        share[i] = caps[i];
        left -= cost(i) * caps[i];
    }
    const double lambda =
        (k < order.size() && suffix[k] > 0 && left > 0) ? left / suffix[k] : 0;
    for (; k < order.size(); ++k) {
        const size_t i = order[k];
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

}  // namespace

std::vector<uint32_t> apportion(const std::vector<double>& weights, double total,
                                const std::vector<uint32_t>& caps,
                                const std::vector<double>& costs) {
    const bool unit = costs.empty();
    auto cost = [&](size_t i) { return unit ? 1.0 : costs[i]; };
    if (unit) total = std::floor(total);
    std::vector<uint32_t> count(weights.size(), 0);
    if (!(total > 0)) return count;

    std::vector<size_t> order;
    for (size_t i = 0; i < weights.size(); ++i)
        if (weights[i] > 0 && caps[i] > 0) order.push_back(i);
    const std::vector<double> share = water_fill(order, weights, caps, total, cost);

    double left = total;
    for (size_t i : order) {
        count[i] = uint32_t(std::min(std::floor(share[i]), double(caps[i])));
        left -= cost(i) * count[i];
    }
    std::vector<RemainderKey> keys;
    keys.reserve(order.size());
    for (size_t i : order) keys.push_back({share[i] - std::floor(share[i]), mix64(i), i});
    if (unit && left >= 0 && left < double(keys.size())) {
        // The usual case: one more unit each for the `left` largest fractional parts.
        // None of them is at its cap (a capped item has fraction 0 and sorts last among
        // them).
        const size_t n = size_t(left);
        std::nth_element(keys.begin(), keys.begin() + n, keys.end());
        for (size_t k = 0; k < n; ++k) {
            if (count[keys[k].index] < caps[keys[k].index]) {
                ++count[keys[k].index];
                left -= 1;
            }
        }
    }
    if (left == 0) return count;
    std::sort(keys.begin(), keys.end());
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
