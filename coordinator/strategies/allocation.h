// Allocation: turning real-valued shares of a sample budget into whole per-pixel counts
// that spend it exactly. Shared by the budgeted strategies (adaptive, optimal,
// optimal-time).
#pragma once

#include <cstdint>
#include <vector>

#include "strategy_params.h"

namespace aliquot {

// Splits `total` among items in proportion to `weights` (>= 0), no item above its `cap`,
// where one unit of item i costs `costs[i]` (empty: every unit costs 1). Capped items
// give their excess to the others (water-filling). Counts are whole: the floors first,
// then one more each in order of the largest fractional part, ties broken by a hash of
// the index so that equal shares are spread over the image rather than given to its first
// rows. With unit costs it spends exactly `total` unless the caps cannot hold it; with
// costs it spends as much as fits without exceeding `total`. Items of weight 0 get
// nothing.
// With `scratch`, the buffers it orders the remainder in are kept there for the next
// call: a strategy that plans rounds of one image again and again (optimal-time's round
// ends at 1920x1080 sorted 32 MB of keys) takes no fresh pages for them.
struct RemainderKey {
    double fraction;  // of the item's real-valued share
    size_t index;
};
struct ApportionScratch {
    std::vector<RemainderKey> keys;
    std::vector<std::vector<uint32_t>> histogram;  // each band's fraction buckets
    std::vector<uint16_t> bucket;                  // each item's, with unit costs
};
// With `kept_total`, the caller's own pass has summed costs[i] * weights[i] (weights[i]
// alone without costs) over the items of weight > 0 and cap > 0, in bands of kBandPixels
// items (bands.h), each in item order and the bands' sums in band order: the sum the
// shares are scaled by, bit for bit, without apportion's pass over every item for it.
std::vector<uint32_t> apportion(const std::vector<double>& weights, double total,
                                const std::vector<uint32_t>& caps,
                                const std::vector<double>& costs = {},
                                ApportionScratch* scratch = nullptr,
                                const double* kept_total = nullptr);

// The samples a budgeted method may spend: `budget`, or spp * pixels when only spp is
// given, and never more than `max_samples` when that is set. Assumes validate() passed.
uint64_t sample_budget(const StrategyParams& params, size_t pixels);

// Per-pixel cap for methods whose max_spp of 0 means "no cap beyond the budget".
inline uint32_t spp_cap(const StrategyParams& params) {
    return params.max_spp ? params.max_spp : UINT32_MAX;
}

}  // namespace aliquot
