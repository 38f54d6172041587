// For tests only, and included by one test file of a test binary: replaces the global
// operator new so that a thread can make every allocation past a size fail, as under an
// address-space limit (prlimit --as) a large allocation fails while small ones are
// still served from memory the heap already holds.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace aliquot::testing {

// Allocations larger than this, made on this thread, throw std::bad_alloc.
inline thread_local size_t allocation_cap = SIZE_MAX;

// Caps the calling thread's allocations while it lives.
class AllocationCap {
public:
    explicit AllocationCap(size_t bytes) { allocation_cap = bytes; }
    ~AllocationCap() { allocation_cap = SIZE_MAX; }
    AllocationCap(const AllocationCap&) = delete;
    AllocationCap& operator=(const AllocationCap&) = delete;
};

}  // namespace aliquot::testing

// The replacements (not inline, as the standard requires): new[] and the nothrow forms
// of libstdc++ call this one. GCC cannot see that this new and this delete pair up.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t size) {
    if (size > aliquot::testing::allocation_cap) throw std::bad_alloc();
    if (void* p = std::malloc(size ? size : 1)) return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop
