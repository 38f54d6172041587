// SampleRng: the random numbers of one pixel sample. Seeded by a hash of
// (render seed, x, y, sample index) and nothing else, so a sample draws the same numbers
// wherever it is traced, and a render is the same bytes however its pixels are split
// among threads, jobs and workers. (Its last bits may also depend on which samples share
// its batch and so Embree's packets, see kCellSide in sample_job.h: the render's rounds
// and a fixed grid of cells fix that, not the workers.)
#pragma once

#include <cstdint>

namespace aliquot {

// SplitMix64's finaliser: a bijective 64-bit mix with full avalanche.
constexpr uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

constexpr uint64_t sample_hash(uint64_t seed, uint32_t x, uint32_t y, uint64_t k) {
    uint64_t h = mix64(seed + 0x9e3779b97f4a7c15ULL);
    h = mix64(h ^ ((uint64_t(x) << 32) | y));
    return mix64(h ^ k);
}

// One PCG32 step (O'Neill, below) on a raw state and increment: SampleRng's, and the
// batched tracer's, which keeps many samples' states side by side (path_lanes.h).
constexpr uint32_t pcg32_step(uint64_t& state, uint64_t inc) {
    const uint64_t old = state;
    state = old * 6364136223846793005ULL + inc;
    const uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
    const uint32_t rot = uint32_t(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((32 - rot) & 31));
}

// Uniform in [0, 1) from 32 random bits: their top 24, so the result is never rounded
// up to 1. (24 bits fit a signed int, whose conversion to float is one instruction.)
constexpr float unit_float(uint32_t bits) { return float(int32_t(bits >> 8)) * 0x1p-24f; }

// PCG32 (O'Neill, "PCG: A Family of Simple Fast Space-Efficient Statistically Good
// Algorithms for Random Number Generation", 2014): 64-bit LCG state, XSH-RR output.
//
// seed_pcg is its seeding on raw state, for code that seeds many samples' generators in
// one vectorised loop (worker/tracer/camera_rays.cpp).
constexpr void seed_pcg(uint64_t seed, uint32_t x, uint32_t y, uint64_t k,
                        uint64_t& state, uint64_t& inc) {
    const uint64_t h = sample_hash(seed, x, y, k);
    inc = (mix64(h ^ 0xda3e39cb94b95bdbULL) << 1) | 1u;
    state = 0;
    pcg32_step(state, inc);
    state += h;
    pcg32_step(state, inc);
}

class SampleRng {
public:
    SampleRng(uint64_t seed, uint32_t x, uint32_t y, uint64_t k) {
        seed_pcg(seed, x, y, k, state_, inc_);
    }
    // The generator at a raw state, as state() and increment() read it.
    static SampleRng at(uint64_t state, uint64_t inc) { return SampleRng(state, inc); }

    uint32_t next_u32() { return pcg32_step(state_, inc_); }
    float next_float() { return unit_float(next_u32()); }

    // The raw generator, for code that steps many samples' generators side by side and
    // hands each its state back.
    uint64_t state() const { return state_; }
    uint64_t increment() const { return inc_; }
    void set_state(uint64_t state) { state_ = state; }

private:
    SampleRng(uint64_t state, uint64_t inc) : state_(state), inc_(inc) {}

    uint64_t state_;
    uint64_t inc_;
};

}  // namespace aliquot
