// PageBuffer: a fixed-size array of plain values whose memory comes zeroed from the
// kernel, mapped at once, with no second pass writing zeros over it. A render's sums
// are ~230 MB at 1920x1080; std::vector's value-initialisation wrote every byte the
// kernel had just zeroed, on top of a page fault for each 4 KiB.
#pragma once

#include <cstddef>
#include <type_traits>
#include <utility>

namespace aliquot {

namespace page_memory {
// `bytes` of zeroed memory; large ones mapped from the kernel, every page in place.
// Throws std::bad_alloc.
void* allocate_zeroed(size_t bytes);
void release(void* memory, size_t bytes);
// Writes a zero into every page, so that later writes take no page faults (a copy
// prepared off the locks for a round end to fill).
void touch(void* memory, size_t bytes);
}  // namespace page_memory

template <class T>
class PageBuffer {
    // Values the kernel's zero bytes may stand for, never constructed or destroyed.
    static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

public:
    PageBuffer() = default;
    explicit PageBuffer(size_t size)
        : data_(static_cast<T*>(page_memory::allocate_zeroed(size * sizeof(T)))),
          size_(size) {}
    PageBuffer(PageBuffer&& other) noexcept
        : data_(std::exchange(other.data_, nullptr)),
          size_(std::exchange(other.size_, 0)) {}
    PageBuffer& operator=(PageBuffer&& other) noexcept {
        if (this != &other) {
            page_memory::release(data_, size_ * sizeof(T));
            data_ = std::exchange(other.data_, nullptr);
            size_ = std::exchange(other.size_, 0);
        }
        return *this;
    }
    PageBuffer(const PageBuffer&) = delete;
    PageBuffer& operator=(const PageBuffer&) = delete;
    ~PageBuffer() { page_memory::release(data_, size_ * sizeof(T)); }

    // Zeroed memory of `size` values unless it holds that many already (then kept as is).
    void resize(size_t size) {
        if (size != size_) *this = PageBuffer(size);
    }
    void touch() { page_memory::touch(data_, size_ * sizeof(T)); }

    size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    T* data() { return data_; }
    const T* data() const { return data_; }
    T& operator[](size_t i) { return data_[i]; }
    const T& operator[](size_t i) const { return data_[i]; }
    T* begin() { return data_; }
    T* end() { return data_ + size_; }
    const T* begin() const { return data_; }
    const T* end() const { return data_ + size_; }

private:
    T* data_ = nullptr;
    size_t size_ = 0;
};

}  // namespace aliquot
