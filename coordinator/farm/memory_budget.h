// The memory budget of the renders a coordinator holds: what one render may take at its
// peak, the default limit, the error a submission past it gets, and the account of what
// the renders in memory hold against it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <string>

namespace aliquot {

// Half of the machine's physical memory (sysconf), or 4 GiB when it cannot be read: the
// default budget for the buffers of the renders a coordinator holds in memory.
uint64_t default_memory_limit();

// What a render's session may hold in memory at its peak, in bytes: the accumulator (96
// bytes a pixel), a round's jobs and the strategy's per-pixel state, the copy of the
// buffers a checkpoint is written from, the final image, and the reference with its
// per-round comparison image when there is one; with first_hits, the first-hit sums
// (AuxSums), their checkpoint copy and the image's layers; with denoises (method
// `denoised`), what its round ends hold: the copies they plan from, the plans' buffers
// and Open Image Denoise's working memory (DenoisedStrategy::round_end_memory).
// docs/FARM.md has the measured numbers.
uint64_t render_memory_estimate(uint32_t width, uint32_t height, bool has_reference,
                                bool first_hits = false, bool denoises = false);
// render_memory_estimate for a render of `method` that asked for first-hit sums or not
// (`aux`): `denoised` keeps them whether or not it was asked (RenderSession turns them
// on) and denoises its round ends. The coordinator counts a submission with it, and the
// CLI checks an embedded render with it before it starts, so both count the same. (A
// name of its own: a method's name as a string literal would convert to the bool of an
// overload.)
uint64_t method_memory_estimate(uint32_t width, uint32_t height, bool has_reference,
                                bool aux, const std::string& method);
// What a refusal says of the largest part of that estimate, when one part dwarfs the
// rest: "" but for denoises, then what denoising the round ends takes.
std::string render_memory_note(uint32_t width, uint32_t height, bool denoises);

// Coordinator::submit refuses a render whose buffers would take the renders in memory
// past the budget. Nothing has changed when it is thrown: no render id, no directory.
class MemoryBudgetError : public std::runtime_error {
public:
    // `note` (render_memory_note), when not empty, follows what the render needs.
    MemoryBudgetError(uint64_t needed, uint64_t in_use, size_t renders, uint64_t limit,
                      const std::string& note = {});
    uint64_t needed, in_use, limit;
};

// What the renders in memory, and the submissions being set up, hold against the limit
// (0: none). Its own lock, a leaf (docs/FARM.md, "Locks"): a submission is checked and
// counted in one step, without the render list's lock.
class MemoryBudget {
public:
    explicit MemoryBudget(uint64_t limit) : limit_(limit) {}
    // Counts `bytes` for one more render, or throws MemoryBudgetError (with `note`) and
    // counts nothing.
    void claim(uint64_t bytes, const std::string& note = {});
    // Counts `bytes` for a render whatever the limit (one resumed at start-up).
    void hold(uint64_t bytes);
    // A render counted so left memory, or its submission failed.
    void release(uint64_t bytes);
    uint64_t in_use() const;
    // What a decoded reference for a width x height render may take: the budget left
    // beside the render's own estimate, plus the estimate's share for the reference's
    // RGB; 0 (no bound) without a limit. Throws MemoryBudgetError when the render itself
    // does not fit now.
    uint64_t reference_allowance(uint32_t width, uint32_t height) const;

private:
    void check_locked(uint64_t bytes, const std::string& note = {}) const;

    const uint64_t limit_;
    mutable std::mutex mutex_;
    uint64_t in_use_ = 0;
    size_t renders_ = 0;
};

}  // namespace aliquot
