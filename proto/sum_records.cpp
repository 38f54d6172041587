#include "sum_records.h"

#include <bit>
#include <cstdint>
#include <cstring>
#include <new>
#include <type_traits>

namespace aliquot {

namespace {

// The records are the structs' bytes on a little-endian machine: no padding, the fields
// in the order aliquot.proto states, each 8 bytes.
static_assert(std::is_trivially_copyable_v<PixelSums> &&
              std::is_standard_layout_v<PixelSums>);
static_assert(sizeof(double) == 8 && sizeof(uint64_t) == 8);
static_assert(sizeof(PixelSums) == kPixelRecordBytes);
static_assert(offsetof(PixelSums, even) == 0 && offsetof(PixelSums, odd) == 24 &&
              offsetof(PixelSums, sum_sq_luminance) == 48 &&
              offsetof(PixelSums, samples) == 56 && offsetof(PixelSums, rays) == 64 &&
              offsetof(PixelSums, nonfinite) == 72);
static_assert(std::is_trivially_copyable_v<FirstHitSums> &&
              std::is_standard_layout_v<FirstHitSums>);
static_assert(sizeof(FirstHitSums) == kFirstHitRecordBytes);
static_assert(offsetof(FirstHitSums, albedo) == 0 &&
              offsetof(FirstHitSums, normal) == 24);

constexpr bool kLittleEndian = std::endian::native == std::endian::little;

// The records' bytes as the structs they are, or null where they cannot be read as such
// in place (none, or not aligned for them: a heap buffer always is).
template <class Sums>
const Sums* as_sums(std::string_view bytes) {
    if (bytes.empty() || reinterpret_cast<uintptr_t>(bytes.data()) % alignof(Sums) != 0)
        return nullptr;
    // The buffer's objects begin where its bytes were copied in (implicit-lifetime
    // types).
    return std::launder(reinterpret_cast<const Sums*>(bytes.data()));
}

// On a little-endian machine one pass each way: the bytes copied in or out, never zeroed
// first; on another, field by field.
template <class Sums>
void copy_out(const SumsArray<Sums>& sums, std::string& out) {
    if constexpr (!kLittleEndian) return portable_records::write_records(sums, out);
    out.assign(reinterpret_cast<const char*>(sums.data()), sums.size() * sizeof(Sums));
}

template <class Sums>
void copy_in(std::string_view bytes, SumsArray<Sums>& out) {
    if constexpr (!kLittleEndian) return portable_records::read_records(bytes, out);
    const size_t n = bytes.size() / sizeof(Sums);
    if (const Sums* sums = as_sums<Sums>(bytes)) return out.assign(sums, sums + n);
    out.resize(n);
    if (n > 0) std::memcpy(out.data(), bytes.data(), n * sizeof(Sums));
}

template <class Sums>
void read_in_place(std::string_view bytes, SumsArray<Sums>& out) {
    const Sums* sums = kLittleEndian ? as_sums<Sums>(bytes) : nullptr;
    if (sums)
        out.borrow(sums, bytes.size() / sizeof(Sums));
    else
        copy_in(bytes, out);
}

void store(uint64_t v, char*& at) {
    for (int b = 0; b < 8; ++b) *at++ = char(uint8_t(v >> (8 * b)));
}
void store(double v, char*& at) { store(std::bit_cast<uint64_t>(v), at); }

uint64_t load_u64(const char*& at) {
    uint64_t v = 0;
    for (int b = 0; b < 8; ++b) v |= uint64_t(uint8_t(*at++)) << (8 * b);
    return v;
}
double load_double(const char*& at) { return std::bit_cast<double>(load_u64(at)); }

}  // namespace

namespace portable_records {

void write_records(const SumsArray<PixelSums>& sums, std::string& out) {
    out.resize(sums.size() * kPixelRecordBytes);
    char* at = out.data();
    for (const PixelSums& p : sums) {
        for (const double v : p.even) store(v, at);
        for (const double v : p.odd) store(v, at);
        store(p.sum_sq_luminance, at);
        store(p.samples, at);
        store(p.rays, at);
        store(p.nonfinite, at);
    }
}

void write_records(const SumsArray<FirstHitSums>& sums, std::string& out) {
    out.resize(sums.size() * kFirstHitRecordBytes);
    char* at = out.data();
    for (const FirstHitSums& f : sums) {
        for (const double v : f.albedo) store(v, at);
        for (const double v : f.normal) store(v, at);
    }
}

void read_records(std::string_view bytes, SumsArray<PixelSums>& out) {
    out.resize(bytes.size() / kPixelRecordBytes);
    const char* at = bytes.data();
    for (PixelSums& p : out) {
        for (double& v : p.even) v = load_double(at);
        for (double& v : p.odd) v = load_double(at);
        p.sum_sq_luminance = load_double(at);
        p.samples = load_u64(at);
        p.rays = load_u64(at);
        p.nonfinite = load_u64(at);
    }
}

void read_records(std::string_view bytes, SumsArray<FirstHitSums>& out) {
    out.resize(bytes.size() / kFirstHitRecordBytes);
    const char* at = bytes.data();
    for (FirstHitSums& f : out) {
        for (double& v : f.albedo) v = load_double(at);
        for (double& v : f.normal) v = load_double(at);
    }
}

}  // namespace portable_records

void write_records(const SumsArray<PixelSums>& sums, std::string& out) {
    copy_out(sums, out);
}
void write_records(const SumsArray<FirstHitSums>& sums, std::string& out) {
    copy_out(sums, out);
}
void read_records(std::string_view bytes, SumsArray<PixelSums>& out) {
    copy_in(bytes, out);
}
void read_records(std::string_view bytes, SumsArray<FirstHitSums>& out) {
    copy_in(bytes, out);
}
void read_records_in_place(std::string_view bytes, SumsArray<PixelSums>& out) {
    read_in_place(bytes, out);
}
void read_records_in_place(std::string_view bytes, SumsArray<FirstHitSums>& out) {
    read_in_place(bytes, out);
}

}  // namespace aliquot
