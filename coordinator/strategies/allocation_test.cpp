#include "allocation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <tuple>

#include "bands.h"
#include "sampler.h"

namespace aliquot {
namespace {

// A sum as apportion takes it: in item order within bands of kBandPixels, the bands'
// sums in band order.
template <typename Term>
double banded_sum(size_t n, const Term& term) {
    double all = 0;
    for (size_t begin = 0; begin < n; begin += kBandPixels) {
        double band = 0;
        for (size_t i = begin; i < std::min(n, begin + kBandPixels); ++i) band += term(i);
        all += band;
    }
    return all;
}

// apportion with unit costs and caps that never bind, the plain way: shares by one
// multiplier (summed in bands, as apportion does), floors, and one more each for
// the `left` largest fractional parts, ties by the index's hash and then the index,
// found by sorting every item.
std::vector<uint32_t> reference(const std::vector<double>& weights, double total) {
    const double all = banded_sum(
        weights.size(), [&](size_t i) { return weights[i] > 0 ? weights[i] : 0.0; });
    const double first = total / all;
    std::vector<uint32_t> count(weights.size());
    std::vector<std::tuple<double, uint64_t, size_t>> keys;  // -fraction: largest first
    uint64_t floors = 0;
    for (size_t i = 0; i < weights.size(); ++i) {
        if (!(weights[i] > 0)) continue;
        const double share = first * weights[i];
        count[i] = uint32_t(std::floor(share));
        floors += count[i];
        keys.emplace_back(-(share - std::floor(share)), mix64(i), i);
    }
    std::sort(keys.begin(), keys.end());
    const size_t left = size_t(total - double(floors));
    for (size_t k = 0; k < left; ++k) ++count[std::get<2>(keys[k])];
    return count;
}

std::vector<uint32_t> no_caps(size_t n) { return std::vector<uint32_t>(n, 1u << 30); }

// Equal weights give every item the same fractional part: the bucket holding the last
// unit given is every item, which is selected in place.
TEST(Apportion, EqualSharesOverManyBandsGoToTheSameItemsAsAFullSort) {
    const size_t n = 5 * kBandPixels + 123;
    const std::vector<double> weights(n, 1.0);
    const double total = 3.0 * double(n) + double(n) / 3;
    const std::vector<uint32_t> got = apportion(weights, total, no_caps(n));
    EXPECT_EQ(got, reference(weights, total));
    uint64_t sum = 0;
    for (uint32_t c : got) sum += c;
    EXPECT_EQ(sum, uint64_t(total));
}

// Weights in a few classes: few items share the last unit's bucket, which is copied out.
TEST(Apportion, VariedSharesOverManyBandsGoToTheSameItemsAsAFullSort) {
    const size_t n = 4 * kBandPixels + 77;
    std::vector<double> weights(n);
    for (size_t i = 0; i < n; ++i) weights[i] = 0.5 + double(mix64(i) % 1000) / 250.0;
    weights[17] = 0;  // gets nothing
    const double total = 2.5 * double(n);
    const std::vector<uint32_t> got = apportion(weights, total, no_caps(n));
    EXPECT_EQ(got, reference(weights, total));
    EXPECT_EQ(got[17], 0u);
}

// Adaptive's case: equal weights within blocks of items, so the ties are whole blocks.
TEST(Apportion, BlocksOfEqualSharesGoToTheSameItemsAsAFullSort) {
    const size_t n = 3 * kBandPixels;
    std::vector<double> weights(n);
    for (size_t i = 0; i < n; ++i) weights[i] = 1.0 + double((i / 256) % 3);
    const double total = 7.0 * double(n) / 3.0 + 11;
    EXPECT_EQ(apportion(weights, total, no_caps(n)), reference(weights, total));
}

// apportion with costs and caps that never bind, the plain way: floors, then the items
// in the order of their fractional parts (ties by the index's hash, then the index),
// found by sorting every item, each given one more unit while its cost fits what is left,
// and again until none fits.
std::vector<uint32_t> reference_with_costs(const std::vector<double>& weights,
                                           const std::vector<double>& costs,
                                           double total) {
    const size_t n = weights.size();
    const double all = banded_sum(
        n, [&](size_t i) { return weights[i] > 0 ? costs[i] * weights[i] : 0.0; });
    const double first = total / all;
    std::vector<uint32_t> count(weights.size());
    std::vector<std::tuple<double, uint64_t, size_t>> keys;  // -fraction: largest first
    for (size_t i = 0; i < weights.size(); ++i) {
        if (!(weights[i] > 0)) continue;
        const double share = first * weights[i];
        count[i] = uint32_t(std::floor(share));
        keys.emplace_back(-(share - std::floor(share)), mix64(i), i);
    }
    double left = total - banded_sum(n, [&](size_t i) {
                      return weights[i] > 0 ? costs[i] * count[i] : 0.0;
                  });
    std::sort(keys.begin(), keys.end());
    for (size_t k = keys.size(); left < 0 && k-- > 0;) {
        const size_t i = std::get<2>(keys[k]);
        if (count[i] > 0) {
            --count[i];
            left += costs[i];
        }
    }
    for (bool gave = true; gave && left > 0;) {
        gave = false;
        for (const auto& key : keys) {
            const size_t i = std::get<2>(key);
            if (costs[i] <= left) {
                ++count[i];
                left -= costs[i];
                gave = true;
                if (!(left > 0)) break;
            }
        }
    }
    return count;
}

// optimal-time's case: every item sorted by its fractional part, in runs counted out by
// their bits and finished by insertion; some shares alike, so ties are broken as well.
TEST(Apportion, WithCostsOverManyBandsGivesWhatAFullSortGives) {
    const size_t n = 3 * kBandPixels + 999;
    std::vector<double> weights(n), costs(n);
    for (size_t i = 0; i < n; ++i) {
        weights[i] = i % 5 == 0 ? 1.0 : 0.25 + double(mix64(i) % 100000) / 7919.0;
        costs[i] = 1.0 + double(mix64(i + n) % 9) / 4.0;
    }
    weights[5] = 0;  // gets nothing
    double cost_of_all = 0;
    for (size_t i = 0; i < n; ++i) cost_of_all += costs[i];
    const double total = 3.3 * cost_of_all;
    const std::vector<uint32_t> got = apportion(weights, total, no_caps(n), costs);
    EXPECT_EQ(got, reference_with_costs(weights, costs, total));
    EXPECT_EQ(got[5], 0u);
}

// The order is sorted only as far as the runs' costs say the reading will go. Here the
// dear items hold the large fractions: the reading gives to them until they no longer
// fit, which the runs' costs foresee, and then goes on, far beyond, to the cheap items,
// whose fractions are all small.
TEST(Apportion, ReadingBeyondWhatTheRunsForesawGivesWhatAFullSortGives) {
    const size_t n = 4 * kBandPixels + 17;
    std::vector<double> weights(n), costs(n);
    double total = 0;
    for (size_t i = 0; i < n; ++i) {
        const double u = double(mix64(i) % 100000) / 100000.0;
        const bool dear = mix64(i + n) % 3 == 0;
        costs[i] = dear ? 1000.0 : 1.0;
        weights[i] = double(2 + i % 5) + (dear ? 0.85 + 0.1 * u : 0.1 * u);  // the share
        total += costs[i] * weights[i];
    }
    EXPECT_EQ(apportion(weights, total, no_caps(n), costs),
              reference_with_costs(weights, costs, total));
}

// The reading stops where what is left reaches 0, so an item that costs nothing, met
// after that point, gets no unit; giving whole runs at once must stop there too. Item 2
// (cost 0) sits between items 0 and 1 in the order; item 0 spends all that is left.
TEST(Apportion, NothingIsGivenOnceWhatIsLeftReachesZeroEvenForFree) {
    for (const size_t n : {size_t(3), 2 * kBandPixels + 7}) {
        std::vector<double> weights(n, 0.0), costs(n, 1.0);
        weights[0] = 0.75, weights[1] = 0.25, weights[2] = 0.5;
        costs[2] = 0.0;
        const std::vector<uint32_t> got =
            apportion(weights, 1.0, std::vector<uint32_t>(n, 10), costs);
        EXPECT_EQ(got[0], 1u) << n;
        EXPECT_EQ(got[1], 0u) << n;
        EXPECT_EQ(got[2], 0u) << n;
    }
}

// A strategy keeps the order's buffer from one round end to the next: what it held
// before, of another size, changes nothing.
TEST(Apportion, AKeptScratchGivesWhatAFreshOneGives) {
    ApportionScratch kept;
    for (const size_t n : {3 * kBandPixels + 5, kBandPixels / 2, 5 * kBandPixels + 1}) {
        std::vector<double> weights(n), costs(n);
        for (size_t i = 0; i < n; ++i) {
            weights[i] = 0.1 + double(mix64(i * 3 + n) % 77777) / 3333.0;
            costs[i] = 1.0 + double(mix64(i + n) % 13) / 3.0;
        }
        const double total = 2.6 * double(n);
        EXPECT_EQ(apportion(weights, total, no_caps(n), costs, &kept),
                  apportion(weights, total, no_caps(n), costs))
            << n;
    }
}

// Caps that bind, with costs: checked against what water-filling means rather than
// against a second copy of it. Every count within its cap; nothing spent beyond the total
// and nothing left that would still buy a unit of any item below its cap; one multiplier
// lambda for all, with the items below their cap within a unit of lambda * w_i and those
// at it having a share that reached it; and the same counts on one thread as on many.
TEST(Apportion, BindingCapsWithCostsFillToOneMultiplier) {
    const size_t n = 2 * kBandPixels + 321;
    std::vector<double> weights(n), costs(n);
    std::vector<uint32_t> caps(n);
    for (size_t i = 0; i < n; ++i) {
        weights[i] = i % 11 == 0 ? 0.0 : 1.0 + double(mix64(i) % 1000) / 100.0;  // 1-11
        costs[i] = 1.0 + double(mix64(i + n) % 7) / 3.0;
        caps[i] = mix64(i + 2 * n) % 4 == 0 ? 3u : 1000u;  // a quarter capped low
    }
    double cost_of_all = 0;
    for (size_t i = 0; i < n; ++i) cost_of_all += costs[i];
    const double total = 20.0 * cost_of_all;  // lambda ~4: the caps of 3 bind
    const std::vector<uint32_t> got = apportion(weights, total, caps, costs);

    double spent = 0;
    for (size_t i = 0; i < n; ++i) {
        ASSERT_LE(got[i], caps[i]) << i;
        if (weights[i] == 0) ASSERT_EQ(got[i], 0u) << i;
        spent += costs[i] * got[i];
    }
    EXPECT_LE(spent, total * (1 + 1e-12));
    for (size_t i = 0; i < n; ++i)
        if (weights[i] > 0 && got[i] < caps[i])
            ASSERT_GT(costs[i], total - spent) << i << ": a unit of it still fits";

    // lambda from the items below their cap: count = floor or ceil of lambda * w_i.
    double lo = 0, hi = HUGE_VAL;
    size_t at_cap = 0;
    for (size_t i = 0; i < n; ++i) {
        if (!(weights[i] > 0)) continue;
        if (got[i] < caps[i]) {
            lo = std::max(lo, (double(got[i]) - 1) / weights[i]);
            hi = std::min(hi, (double(got[i]) + 1) / weights[i]);
        } else {
            ++at_cap;
        }
    }
    EXPECT_LE(lo, hi) << "no one multiplier fits every item below its cap";
    EXPECT_GT(at_cap, n / 8);  // the low caps did bind
    for (size_t i = 0; i < n; ++i)
        if (weights[i] > 0 && got[i] == caps[i])
            ASSERT_GE(hi * weights[i], double(caps[i]) - 1) << i << ": capped too early";

    const unsigned threads = band_threads();
    set_band_threads(1);
    EXPECT_EQ(apportion(weights, total, caps, costs), got);
    set_band_threads(threads);
}

TEST(Apportion, WithinOneBandGoesToTheSameItemsAsAFullSort) {
    const size_t n = 1000;
    std::vector<double> weights(n, 2.0);
    for (size_t i = 0; i < n; i += 3) weights[i] = 1.0;
    const double total = 1234.0;
    EXPECT_EQ(apportion(weights, total, no_caps(n)), reference(weights, total));
}

}  // namespace
}  // namespace aliquot
