// Strategy: decides where a render's next samples go. It sees only the merged buffers at a
// round boundary (never arrival order or timings), so its decisions are deterministic.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "accumulator.h"

namespace aliquot {

struct Round {
    uint32_t index = 0;
    std::vector<uint32_t> spp;  // samples each pixel gets this round, row-major
    uint64_t total() const {
        uint64_t n = 0;
        for (uint32_t s : spp) n += s;
        return n;
    }
};

class Strategy {
public:
    virtual ~Strategy() = default;
    virtual std::string name() const = 0;
    // The next round given everything merged so far, or nullopt when the render is done.
    virtual std::optional<Round> next_round(const Accumulator& merged) = 0;
    // Samples the render expects to spend in all, for progress; an upper bound for
    // methods that stop early.
    virtual uint64_t planned_samples() const = 0;
};

}  // namespace aliquot
