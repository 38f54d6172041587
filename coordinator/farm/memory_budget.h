// The memory budget of the renders a coordinator holds: what one render may take at its
// peak, the default limit, and the error a submission past it gets.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>

namespace aliquot {

// Half of the machine's physical memory (sysconf), or 4 GiB when it cannot be read: the
// default budget for the buffers of the renders a coordinator holds in memory.
uint64_t default_memory_limit();

// What a render's session may hold in memory at its peak, in bytes: the accumulator (96
// bytes a pixel), a round's jobs and the strategy's per-pixel state, the copy of the
// buffers a checkpoint is written from, the final image, and the reference with its
// per-round comparison image when there is one. docs/FARM.md has the measured numbers.
uint64_t render_memory_estimate(uint32_t width, uint32_t height, bool has_reference);

// Coordinator::submit refuses a render whose buffers would take the renders in memory
// past the budget. Nothing has changed when it is thrown: no render id, no directory.
class MemoryBudgetError : public std::runtime_error {
public:
    MemoryBudgetError(uint64_t needed, uint64_t in_use, size_t renders, uint64_t limit);
    uint64_t needed, in_use, limit;
};

}  // namespace aliquot
