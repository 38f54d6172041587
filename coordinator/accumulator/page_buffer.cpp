#include "page_buffer.h"

#include <sys/mman.h>

#include <cstdint>
#include <cstdlib>
#include <new>

namespace aliquot::page_memory {

namespace {

// Below this calloc's zeroing costs little; at and above it, memory is mapped whole.
constexpr size_t kMapped = size_t(1) << 21;
constexpr size_t kPage = 4096;

size_t mapped_bytes(size_t bytes) { return (bytes + kPage - 1) / kPage * kPage; }

}  // namespace

void* allocate_zeroed(size_t bytes) {
    if (bytes == 0) return nullptr;
    if (bytes < kMapped) {
        void* memory = std::calloc(1, bytes);
        if (!memory) throw std::bad_alloc();
        return memory;
    }
    // Not advised to use huge pages (MADV_HUGEPAGE): with the kernel's defrag setting
    // "madvise", the default, an advised fault compacts memory to find a huge page, and
    // faulting in 232 MB took 0.40-0.54 s of CPU that way against 0.10 s in 4 KiB pages
    // (and 0.13-0.16 s with a vector's zeroing pass on top; docs/PERFORMANCE.md).
    void* memory = mmap(nullptr, mapped_bytes(bytes), PROT_READ | PROT_WRITE,
                        MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (memory == MAP_FAILED) throw std::bad_alloc();
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
