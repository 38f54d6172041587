// The order in which apportion (allocation.h) gives the units its floors leave: largest
// fractional part first, ties by a hash of the index; the fraction buckets and runs it is
// counted and sorted in, and the selection of its first items. Private to allocation.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "apportion_shares.h"
#include "sampler.h"

namespace aliquot::apportioning {

// A remainder fraction's bucket: floor(fraction * kFractionBuckets), which never falls
// as the fraction rises, so the buckets are in the fractions' order. Fractions lie in
// [0, 1) and spread evenly over it, so each bucket holds about as many items (~120 at
// 1920x1080); bucketing by the top bits of their bit patterns put half of them, those
// in [0.5, 1), into 16 buckets, whose sorts were most of optimal-time's round end.
constexpr size_t kFractionBuckets = size_t(1) << 14;
inline size_t fraction_bucket(double fraction) {
    // (Multiplying by a power of two is exact; a NaN, which no share gives, goes first.)
    return fraction > 0 ? std::min(kFractionBuckets - 1,
                                   size_t(fraction * double(kFractionBuckets)))
                        : 0;
}

// The remainder order is sorted in runs (see apportion): a key's rank is the top 21
// bits of its fraction, reversed (largest first); its top 8 bits pick its run, so a run
// holds 64 of the histogram's buckets.
constexpr int kRankBits = 21, kFineBits = 13;
constexpr size_t kRuns = size_t(1) << (kRankBits - kFineBits);
constexpr size_t kFine = size_t(1) << kFineBits;
static_assert((size_t(1) << kRankBits) == kFractionBuckets * 128);
inline size_t rank(double fraction) {
    constexpr size_t kTop = (size_t(1) << kRankBits) - 1;
    const size_t d =
        fraction > 0 ? std::min(kTop, size_t(fraction * double(size_t(1) << kRankBits)))
                     : 0;
    return kTop - d;
}
inline size_t run_of_bucket(size_t bucket) {
    return kRuns - 1 - bucket / (kFractionBuckets / kRuns);
}

inline uint64_t bits_of(double v) {
    uint64_t b;
    std::memcpy(&b, &v, sizeof b);
    return b;
}

// The order in which items receive the remainder: largest fractional part first, ties
// by a hash of the index (so that equal shares are spread over the image), then by the
// index. It is total, so the first n items in it are one set however they are found.
// Fractions are >= 0, whose bit patterns sort as their values do.
struct RemainderOrder {
    const Shares& share;
    double fraction(size_t i) const {
        const double s = share(i);
        return s - std::floor(s);
    }
    bool operator()(size_t a, size_t b) const {
        const double fa = fraction(a), fb = fraction(b);
        if (fa != fb) return fa > fb;
        const uint64_t ha = mix64(a), hb = mix64(b);
        return ha != hb ? ha < hb : a < b;
    }
};

// Items still tied with the n-th: their indices, in item order, and the range of their
// fractions' and hashes' bit patterns (which says where they still differ).
struct Tied {
    Scratch<size_t> items;
    uint64_t fraction_lo = ~uint64_t(0), fraction_hi = 0;
    uint64_t hash_lo = ~uint64_t(0), hash_hi = 0;
    void note(uint64_t f, uint64_t h) {
        fraction_lo = std::min(fraction_lo, f), fraction_hi = std::max(fraction_hi, f);
        hash_lo = std::min(hash_lo, h), hash_hi = std::max(hash_hi, h);
    }
    void note(const Tied& o) {
        fraction_lo = std::min(fraction_lo, o.fraction_lo);
        fraction_hi = std::max(fraction_hi, o.fraction_hi);
        hash_lo = std::min(hash_lo, o.hash_lo), hash_hi = std::max(hash_hi, o.hash_hi);
    }
};

// Gives one more unit to item i unless it is at its cap; returns whether it did.
inline bool give(size_t i, std::vector<uint32_t>& count,
                 const std::vector<uint32_t>& caps) {
    if (count[i] >= caps[i]) return false;
    ++count[i];
    return true;
}

// Of `tied`, all tied with each other in RemainderOrder as far as the digits looked at so
// far, gives one more unit to the `wanted` first (below their caps); returns how many it
// gave. Each step takes the next 12 bits where the tied items still differ, first of
// their fractions (largest first) and, once those are all equal, of their hashes
// (smallest first), counts the items by them in bands, gives to every item of a better
// digit than the one holding the wanted-th, and keeps those of that digit. A few are
// left when selection finishes; no full keys are ever stored.
size_t give_to_first(Tied tied, size_t wanted, const RemainderOrder& order,
                     std::vector<uint32_t>& count, const std::vector<uint32_t>& caps);

}  // namespace aliquot::apportioning
