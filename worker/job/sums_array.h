// A result's sums, one per pixel of its rect: owned, as in a std::vector (what a worker
// traces into, what a test builds), or borrowed: read where the bytes of a message
// already hold them (wire.h's from_proto_in_place), so the coordinator's merge reads a
// worker's sums where protobuf parsed them, with no copy of its own (issue 33).
#pragma once

#include <algorithm>
#include <cstddef>
#include <utility>
#include <vector>

namespace aliquot {

// Reading is the same either way. A borrowed array is never carried off: a copy or a
// move of it, and any change to it, owns a copy of its sums first, so whatever outlives
// the message (a result held for the round ahead) owns what it reads. Moving a borrowed
// array therefore copies, and may throw.
template <class T>
class SumsArray {
public:
    using value_type = T;
    using size_type = size_t;
    using reference = T&;
    using const_reference = const T&;
    using iterator = T*;
    using const_iterator = const T*;

    SumsArray() = default;
    SumsArray(const SumsArray& other) : owned_(other.begin(), other.end()) {}
    SumsArray(SumsArray&& other)
        : owned_(other.borrowed_ ? std::vector<T>(other.begin(), other.end())
                                 : std::move(other.owned_)) {}
    SumsArray& operator=(const SumsArray& other) {
        if (this != &other) assign(other.begin(), other.end());
        return *this;
    }
    SumsArray& operator=(SumsArray&& other) {
        if (this == &other) return *this;
        if (other.borrowed_) return *this = other;
        owned_ = std::move(other.owned_);
        borrowed_ = nullptr;
        return *this;
    }

    // Reads the `n` sums at `sums` there from now on: they must stay, unchanged, for as
    // long as this array is read.
    void borrow(const T* sums, size_t n) noexcept {
        owned_ = std::vector<T>();
        borrowed_ = n > 0 ? sums : nullptr;
        borrowed_size_ = n;
    }
    bool borrows() const noexcept { return borrowed_ != nullptr; }

    size_t size() const noexcept { return borrowed_ ? borrowed_size_ : owned_.size(); }
    bool empty() const noexcept { return size() == 0; }
    const T* data() const noexcept { return borrowed_ ? borrowed_ : owned_.data(); }
    const T* begin() const noexcept { return data(); }
    const T* end() const noexcept { return data() + size(); }
    const T& operator[](size_t i) const noexcept { return data()[i]; }
    const T& back() const noexcept { return data()[size() - 1]; }

    T* data() {
        own();
        return owned_.data();
    }
    T* begin() { return data(); }
    T* end() { return data() + owned_.size(); }
    T& operator[](size_t i) { return data()[i]; }
    T& back() { return data()[owned_.size() - 1]; }

    void resize(size_t n) {
        own();
        owned_.resize(n);
    }
    void reserve(size_t n) {
        own();
        owned_.reserve(n);
    }
    void assign(size_t n, const T& value) {
        owned_.assign(n, value);
        borrowed_ = nullptr;
    }
    // Copies [first, last) without value-initialising first (one pass, not two).
    template <class It>
    void assign(It first, It last) {
        owned_.assign(first, last);
        borrowed_ = nullptr;
    }
    void clear() noexcept {
        owned_.clear();
        borrowed_ = nullptr;
    }
    void push_back(const T& value) {
        own();
        owned_.push_back(value);
    }
    template <class... Args>
    T& emplace_back(Args&&... args) {
        own();
        return owned_.emplace_back(std::forward<Args>(args)...);
    }
    void pop_back() {
        own();
        owned_.pop_back();
    }

    friend bool operator==(const SumsArray& a, const SumsArray& b) {
        return std::equal(a.begin(), a.end(), b.begin(), b.end());
    }

private:
    void own() {
        if (!borrowed_) return;
        owned_.assign(borrowed_, borrowed_ + borrowed_size_);
        borrowed_ = nullptr;
    }

    std::vector<T> owned_;
    const T* borrowed_ = nullptr;  // set: the sums are read there, owned_ is empty
    size_t borrowed_size_ = 0;
};

}  // namespace aliquot
