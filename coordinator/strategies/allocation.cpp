#include "allocation.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "apportion_shares.h"
#include "bands.h"
#include "remainder_order.h"

namespace aliquot {

std::vector<uint32_t> apportion(const std::vector<double>& weights, double total,
                                const std::vector<uint32_t>& caps,
                                const std::vector<double>& costs,
                                ApportionScratch* scratch, const double* kept_total) {
    using namespace apportioning;  // apportion_shares.h, remainder_order.h
    const bool unit = costs.empty();
    auto cost = [&](size_t i) { return unit ? 1.0 : costs[i]; };
    if (unit) total = std::floor(total);
    const size_t n = weights.size();
    std::vector<uint32_t> count(n, 0);
    if (!(total > 0)) return count;
    // Without a branch: which items are kept is as unpredictable as which pixels' gaps
    // are 0, and the passes below take no branch on it where they need not.
    const auto keep = [&](size_t i) { return (weights[i] > 0) & (caps[i] > 0); };

    // The passes over every item run in bands on the pool's threads (bands.h); what is
    // summed in floating point is summed in item order within each band and the bands'
    // sums in band order, so the counts are the same whatever the threads. Nothing per
    // item is stored but the counts (and the shares when a cap binds): fractions, hashes
    // and bucket numbers are computed again where they are needed, which at 1920x1080 is
    // cheaper than the ~100 MB of fresh pages that keys, orders and shares took.
    Shares share = proportional_shares(weights, total, keep, cost, kept_total);
    const RemainderOrder order{share};

    // Floors, and how many items' fractions fall in each bucket (fraction_bucket), by
    // band; in the first pass, whether any proportional share reaches its cap too, in
    // which case the caps are bound and the pass is made again with the shares they
    // leave (the usual case is that none does).
    const size_t bands = band_count(n, kBandPixels);
    const bool one_band = bands <= 1;  // then a histogram would cost more than it saves
    std::vector<uint64_t> band_floors(bands, 0);
    std::vector<size_t> band_kept(bands, 0);
    ApportionScratch local;
    ApportionScratch& kept_buffers = scratch ? *scratch : local;
    // Every band's is filled anew by the floors' pass (several bands) or not read (one).
    std::vector<std::vector<uint32_t>>& histogram = kept_buffers.histogram;
    histogram.resize(bands);
    // With costs, each band's cheapest kept item, and what its items of each run of the
    // remainder order cost (that order is sorted only as far as these say it will be
    // read).
    std::vector<double> band_cheapest(bands, unit ? 1.0 : HUGE_VAL);
    std::vector<double> band_spent(bands, 0.0);  // with costs: what the floors cost
    std::vector<std::vector<double>> run_cost(unit || one_band ? 0 : bands);
    std::vector<char> band_capped(bands, 0);
    // With several bands, each item's fraction bucket as the floors' pass found it
    // (kNotKept for an item not kept), so that the passes after it (`gather`, and with
    // costs `put_in_place`, whose runs are the buckets' top 8 bits) read 2 bytes an item
    // instead of working its share out again (half of their time at 1920x1080).
    constexpr uint16_t kNotKept = UINT16_MAX;
    static_assert(kFractionBuckets <= kNotKept);
    const bool keep_buckets = !one_band;
    Scratch<uint16_t> local_buckets;
    uint16_t* bucket_of = nullptr;
    if (keep_buckets) {
        if (scratch) {
            scratch->bucket.resize(n);
            bucket_of = scratch->bucket.data();
        } else {
            local_buckets.resize(n);
            bucket_of = local_buckets.data();
        }
    }
    const auto floors_pass = [&](bool check_caps) {
        for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
            uint64_t floors = 0;
            size_t kept = 0;
            std::vector<uint32_t>& h = histogram[band];
            if (!one_band) h.assign(kFractionBuckets, 0);
            double* spend = nullptr;
            if (!run_cost.empty()) {
                run_cost[band].assign(kRuns, 0.0);
                spend = run_cost[band].data();
            }
            double cheapest = unit ? 1.0 : HUGE_VAL, spent = 0;
            bool capped = false;
            // Every item is visited alike: one not kept has a share of 0 and adds 0
            // everywhere, which leaves each sum as it was, bit for bit.
            for (size_t i = begin; i < end; ++i) {
                const bool k = keep(i);
                const double s = k ? share(i) : 0.0, whole = std::floor(s);
                if (check_caps) capped = capped | (k & (s >= caps[i]));
                count[i] = uint32_t(std::min(whole, double(caps[i])));
                floors += count[i];
                kept += k;
                if (!one_band) {
                    const size_t bucket = fraction_bucket(s - whole);
                    h[bucket] += k;
                    if (bucket_of) bucket_of[i] = k ? uint16_t(bucket) : kNotKept;
                }
                if (!unit) {
                    const double c = k ? cost(i) : 0.0;
                    cheapest = std::min(cheapest, k ? c : HUGE_VAL);
                    spent += c * count[i];
                    if (spend) spend[run_of_bucket(fraction_bucket(s - whole))] += c;
                }
            }
            band_floors[band] = floors;
            band_kept[band] = kept;
            band_cheapest[band] = cheapest;
            band_spent[band] = spent;
            band_capped[band] = capped;
        });
    };
    floors_pass(true);
    if (std::find(band_capped.begin(), band_capped.end(), 1) != band_capped.end()) {
        bind_caps(share, caps, total, keep, cost);
        floors_pass(false);
    }
    size_t kept = 0;
    for (size_t k : band_kept) kept += k;
    double cheapest = HUGE_VAL;  // no item costs less: a smaller `left` buys nothing
    for (double c : band_cheapest) cheapest = std::min(cheapest, c);
    const auto in_bucket = [&](size_t bucket) {
        size_t m = 0;
        for (const std::vector<uint32_t>& h : histogram) m += h[bucket];
        return m;
    };
    // The kept items whose fractions fall in `bucket`, in item order, with the ranges
    // of their fractions and hashes; those in a bucket above it (larger fractions) get
    // one more unit each (below their caps), without a branch, and are counted in
    // `band_given`.
    const auto gather = [&](size_t bucket, std::vector<size_t>& band_given) {
        std::vector<size_t> offset(bands + 1, 0);
        for (size_t b = 0; b < bands; ++b)
            offset[b + 1] = offset[b] + histogram[b][bucket];
        Tied tied;
        tied.items.resize(offset[bands]);
        std::vector<Tied> band_tied(bands);
        for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
            size_t t = offset[band], given = 0;
            for (size_t i = begin; i < end; ++i) {
                const size_t b = bucket_of[i];  // kNotKept: above every bucket
                if (b == bucket) {              // a few of every band
                    tied.items[t++] = i;
                    band_tied[band].note(bits_of(order.fraction(i)), mix64(i));
                }
                const bool up = (b != kNotKept) & (b > bucket) & (count[i] < caps[i]);
                count[i] += up;
                given += up;
            }
            band_given[band] = given;
        });
        for (const Tied& t : band_tied) tied.note(t);
        return tied;
    };
    // The first `wanted` kept items in RemainderOrder get one more unit each (below their
    // caps): the bucket holding the wanted-th is found from the histogram, every item of
    // a larger bucket gets its unit, and only that bucket's items are looked at further.
    const auto give_to_first_of_all = [&](size_t wanted) {
        size_t bucket = kFractionBuckets;
        while (bucket-- > 0) {
            const size_t m = in_bucket(bucket);
            if (wanted <= m) break;
            wanted -= m;
        }
        std::vector<size_t> band_given(bands, 0);
        Tied tied = gather(bucket, band_given);
        size_t given = give_to_first(std::move(tied), wanted, order, count, caps);
        for (size_t g : band_given) given += g;
        return given;
    };

    double left = total;
    if (unit) {
        // Whole numbers far below 2^53: the difference is exact, as the running
        // subtraction was.
        uint64_t floors = 0;
        for (uint64_t f : band_floors) floors += f;
        left = total - double(floors);
    } else {
        double spent = 0;
        for (double s : band_spent) spent += s;
        left = total - spent;
    }
    if (unit && left > 0 && left < double(kept)) {
        // The usual case: one more unit each for the `left` first items in
        // RemainderOrder (none of them is at its cap: a capped item has fraction 0 and
        // comes last among them). The bucket holding the left-th is found from the
        // histogram; every item of a larger bucket gets its unit, and only that bucket's
        // items are looked at further.
        size_t given = 0;
        if (one_band) {
            std::vector<size_t> items;
            items.reserve(kept);
            for (size_t i = 0; i < n; ++i)
                if (keep(i)) items.push_back(i);
            const size_t wanted = size_t(left);
            std::nth_element(items.begin(), items.begin() + (wanted - 1), items.end(),
                             order);
            for (size_t k = 0; k < wanted; ++k) given += give(items[k], count, caps);
        } else {
            given = give_to_first_of_all(size_t(left));
        }
        left -= double(given);
    }
    if (left == 0) return count;

    // Every kept item in RemainderOrder, with its fraction beside it so that sorting
    // reads no weights. The order is read from its start, and with costs the reading
    // ends once `left` buys nothing, about halfway: so it is built in runs (largest
    // fractions first); the runs the reading would pass whole give their items a unit
    // each without being ordered, and a run is put in place and sorted only when the
    // reading may reach it. A full sort of all of them was the largest part of
    // optimal-time's round end at 1920x1080.
    using Key = RemainderKey;
    const auto before = [](const Key& a, const Key& b) {
        if (a.fraction != b.fraction) return a.fraction > b.fraction;
        const uint64_t ha = mix64(a.index), hb = mix64(b.index);
        return ha != hb ? ha < hb : a.index < b.index;
    };
    std::vector<Key>& sorted = kept_buffers.keys;
    sorted.resize(kept);
    std::vector<size_t> start(kRuns + 1, 0);  // where each run's keys go
    std::vector<std::vector<size_t>> at;      // where each band's next key of a run goes
    // Puts runs [from, upto) in place: scattered in bands, each run (~8 K keys at
    // 1920x1080) then counted out by the other 13 bits of its rank in cache, which leaves
    // it nearly sorted, and an insertion sort finishes it, in RemainderOrder's exact
    // order. Runs are shared among the pool's threads. (A scatter into the 16384
    // buckets of the histogram was slower than all the rest.) With `give_below`, the
    // items of the runs before it get one more unit in the same pass.
    const auto put_in_place = [&](size_t from, size_t upto, size_t give_below = 0) {
        if (upto <= from && give_below == 0) return;
        for_each_band(n, kBandPixels, [&](size_t band, size_t begin, size_t end) {
            std::vector<size_t>& next = at[band];
            for (size_t i = begin; i < end; ++i) {
                if (bucket_of[i] == kNotKept) continue;
                // rank(f) >> kFineBits, f the item's fraction: both take its top bits.
                const size_t r = run_of_bucket(bucket_of[i]);
                if (r < give_below)
                    ++count[i];
                else if (r >= from && r < upto)
                    sorted[next[r]++] = {order.fraction(i), i};
            }
        });
        for_each_band(upto - from, 4, [&](size_t, size_t begin, size_t end) {
            std::vector<Key> spread;
            std::vector<uint32_t> at_fine(kFine + 1);
            for (size_t r = from + begin; r < from + end; ++r) {
                Key* const first = sorted.data() + start[r];
                Key* const last = sorted.data() + start[r + 1];
                const size_t m = size_t(last - first);
                if (m > 64) {
                    std::fill(at_fine.begin(), at_fine.end(), 0);
                    for (const Key* k = first; k != last; ++k)
                        ++at_fine[(rank(k->fraction) & (kFine - 1)) + 1];
                    for (size_t j = 0; j < kFine; ++j) at_fine[j + 1] += at_fine[j];
                    spread.resize(m);
                    for (const Key* k = first; k != last; ++k)
                        spread[at_fine[rank(k->fraction) & (kFine - 1)]++] = *k;
                    std::copy(spread.begin(), spread.end(), first);
                }
                for (Key* k = first + 1; k < last; ++k) {  // insertion sort
                    const Key key = *k;
                    Key* j = k;
                    for (; j != first && before(key, j[-1]); --j) *j = j[-1];
                    *j = key;
                }
            }
        });
    };
    // The reading starts at run first_run (those before it had their units given
    // whole) and may read up to position `ready`, where run runs_ready begins.
    size_t first_run = 0, runs_ready = kRuns, ready = kept;
    const auto prepare = [&](size_t upto) {
        put_in_place(runs_ready, upto);
        runs_ready = std::max(runs_ready, upto);
        ready = start[runs_ready];
    };
    if (one_band) {
        for (size_t i = 0, k = 0; i < n; ++i)
            if (keep(i)) sorted[k++] = {order.fraction(i), i};
        std::sort(sorted.begin(), sorted.end(), before);
    } else {
        at.assign(bands, std::vector<size_t>(kRuns, 0));
        for (size_t band = 0; band < bands; ++band)
            for (size_t b = 0; b < kFractionBuckets; ++b)
                at[band][run_of_bucket(b)] += histogram[band][b];
        size_t place = 0;
        for (size_t r = 0; r < kRuns; ++r) {
            start[r] = place;
            for (size_t band = 0; band < bands; ++band) {
                const size_t m = at[band][r];
                at[band][r] = place;
                place += m;
            }
        }
        start[kRuns] = place;
        size_t reach = kRuns;
        if (!unit && left > 0 && !share.capped) {
            // The reading below gives a unit to each item it meets while the item's cost
            // fits in what is left, and no uncapped share's floor is at its cap. So while
            // what the runs cost so far fits, every item of them would get its unit: they
            // get it here, in one pass in bands, unordered, and `left` pays what those
            // runs cost (summed in band order, then run order). A run fits only while
            // something is left after it: the reading stops where `left` reaches 0, so an
            // item costing nothing after that point gets no unit. The reading starts at
            // the first run that does not fit whole; it is put in place with the next
            // (items of that run that do not fit leave room for later ones), and the rest
            // only if the reading goes further.
            double spend = 0;
            for (; first_run < kRuns; ++first_run) {
                double run = 0;
                for (size_t band = 0; band < bands; ++band)
                    run += run_cost[band][first_run];
                if (!(spend + run < left)) break;
                spend += run;
            }
            left -= spend;
            reach = std::min(kRuns, first_run + 2);
        }
        put_in_place(first_run, reach, first_run);
        runs_ready = reach;
        ready = start[reach];
    }
    const auto all_ready = [&] { prepare(kRuns); };
    // Rounding can leave the floors a unit over the total: take it back from the smallest
    // fractional parts.
    if (left < 0) all_ready();
    for (size_t k = sorted.size(); left < 0 && k-- > 0;) {
        const size_t i = sorted[k].index;
        if (count[i] > 0) {
            --count[i];
            left += cost(i);
        }
    }
    // Once `left` is below every item's cost nothing more can be given: reading on (or
    // another pass) would change no count, so the reading stops there.
    const auto spent = [&] { return !(left > 0) || left < cheapest; };
    // The first pass reads on from the runs given whole (which count as given in it).
    size_t from = start[first_run];
    for (bool gave = first_run > 0, first_pass = true; (first_pass || gave) && !spent();
         first_pass = false) {
        if (!first_pass && from > 0) {  // another pass reads the whole order
            put_in_place(0, first_run);
            from = 0;
        }
        if (!first_pass) gave = false;
        for (size_t k = from; k < sorted.size(); ++k) {
            if (k == ready) all_ready();
            // Items come in no order of their own: their counts, caps and costs are
            // fetched ahead (this loop was memory-bound).
            if (k + 16 < ready) {
                const size_t ahead = sorted[k + 16].index;
                __builtin_prefetch(&count[ahead]);
                __builtin_prefetch(&caps[ahead]);
                if (!unit) __builtin_prefetch(&costs[ahead]);
            }
            const size_t i = sorted[k].index;
            if (count[i] < caps[i] && cost(i) <= left) {
                ++count[i];
                left -= cost(i);
                gave = true;
                if (spent()) break;
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
