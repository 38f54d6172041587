#include "page_buffer.h"

#include <sys/mman.h>

#include <cstdint>
#include <cstdlib>
#include <new>

namespace aliquot::page_memory {

namespace {

// Below this calloc's zeroing costs little; at and above it, memory is mapped whole.
constexpr size_t kMapped = size_t(1) << 21;  // one huge page
constexpr size_t kPage = 4096;

// Mapped sizes are rounded up to whole huge pages, and the mapping aligned to one:
// transparent huge pages cover only aligned 2 MiB spans of an advised mapping.
size_t mapped_bytes(size_t bytes) { return (bytes + kMapped - 1) / kMapped * kMapped; }

}  // namespace

void* allocate_zeroed(size_t bytes) {
    if (bytes == 0) return nullptr;
    if (bytes < kMapped) {
        void* memory = std::calloc(1, bytes);
        if (!memory) throw std::bad_alloc();
        return memory;
    }
    const size_t size = mapped_bytes(bytes);
    void* raw = mmap(nullptr, size + kMapped, PROT_READ | PROT_WRITE,
                     MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (raw == MAP_FAILED) throw std::bad_alloc();
    // The slack before and after the aligned span goes back at once.
    const uintptr_t begin = reinterpret_cast<uintptr_t>(raw);
    const uintptr_t aligned = (begin + kMapped - 1) / kMapped * kMapped;
    if (aligned > begin) munmap(raw, aligned - begin);
    const size_t after = begin + size + kMapped - (aligned + size);
    if (after > 0) munmap(reinterpret_cast<void*>(aligned + size), after);
    void* memory = reinterpret_cast<void*>(aligned);
    madvise(memory, size, MADV_HUGEPAGE);  // advice: where refused, 4 KiB pages
    return memory;
}

void release(void* memory, size_t bytes) {
    if (!memory) return;
    if (bytes < kMapped)
        std::free(memory);
    else
        munmap(memory, mapped_bytes(bytes));
}

void touch(void* memory, size_t bytes) {
    if (!memory) return;
#ifdef MADV_POPULATE_WRITE
    if (bytes >= kMapped &&
        madvise(memory, mapped_bytes(bytes), MADV_POPULATE_WRITE) == 0)
        return;
#endif
    // Each page read and written back: its contents stay.
    volatile char* p = static_cast<char*>(memory);
    for (size_t i = 0; i < bytes; i += kPage) p[i] = p[i];
}

}  // namespace aliquot::page_memory
