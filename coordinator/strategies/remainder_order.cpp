#include "remainder_order.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "bands.h"

namespace aliquot::apportioning {

size_t give_to_first(Tied tied, size_t wanted, const RemainderOrder& order,
                     std::vector<uint32_t>& count, const std::vector<uint32_t>& caps) {
    size_t given = 0;
    constexpr int kDigitBits = 12;
    constexpr size_t kDigits = size_t(1) << kDigitBits;
    while (wanted > 0) {
        Scratch<size_t>& items = tied.items;
        if (items.size() <= 4096 ||
            (tied.fraction_lo == tied.fraction_hi && tied.hash_lo == tied.hash_hi)) {
            const size_t n = std::min(wanted, items.size());
            std::nth_element(items.begin(), items.begin() + (n - 1), items.end(), order);
            for (size_t k = 0; k < n; ++k) given += give(items[k], count, caps);
            return given;
        }
        const bool by_fraction = tied.fraction_lo != tied.fraction_hi;
        const uint64_t lo = by_fraction ? tied.fraction_lo : tied.hash_lo;
        const uint64_t hi = by_fraction ? tied.fraction_hi : tied.hash_hi;
        // The tied items share every bit above the highest where lo and hi differ: the
        // next digit is the kDigitBits from there down, in the same order as the values.
        const int top = 63 - __builtin_clzll(lo ^ hi);
        const int shift = std::max(0, top + 1 - kDigitBits);
        const auto digit = [&](size_t i) {
            const uint64_t key = by_fraction ? bits_of(order.fraction(i)) : mix64(i);
            const size_t d = size_t((key >> shift) & (kDigits - 1));
            return by_fraction ? kDigits - 1 - d : d;  // first in the order: digit 0
        };
        const size_t bands = band_count(items.size(), kBandPixels);
        std::vector<std::vector<uint32_t>> histogram(bands);
        for_each_band(items.size(), kBandPixels,
                      [&](size_t band, size_t begin, size_t end) {
                          std::vector<uint32_t>& h = histogram[band];
                          h.assign(kDigits, 0);
                          for (size_t k = begin; k < end; ++k) ++h[digit(items[k])];
                      });
        size_t d = 0;
        for (;; ++d) {
            size_t in_digit = 0;
            for (const std::vector<uint32_t>& h : histogram) in_digit += h[d];
            if (wanted <= in_digit) break;
            wanted -= in_digit;
        }
        std::vector<size_t> offset(bands + 1, 0);
        for (size_t b = 0; b < bands; ++b) offset[b + 1] = offset[b] + histogram[b][d];
        std::vector<Tied> band_tied(bands);
        std::vector<size_t> band_given(bands, 0);
        Tied next;
        next.items.resize(offset[bands]);
        for_each_band(items.size(), kBandPixels,
                      [&](size_t band, size_t begin, size_t end) {
                          size_t t = offset[band], g = 0;
                          Tied& range = band_tied[band];
                          for (size_t k = begin; k < end; ++k) {
                              const size_t i = items[k], di = digit(i);
                              if (di < d) {
                                  g += give(i, count, caps);
                              } else if (di == d) {
                                  next.items[t++] = i;
                                  range.note(bits_of(order.fraction(i)), mix64(i));
                              }
                          }
                          band_given[band] = g;
                      });
        for (size_t b = 0; b < bands; ++b) {
            given += band_given[b];
            next.note(band_tied[b]);
        }
        tied = std::move(next);
    }
    return given;
}

}  // namespace aliquot::apportioning
