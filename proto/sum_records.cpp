#include "sum_records.h"

#include <bit>
#include <cstdint>
#include <cstring>
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

template <class Sums>
void copy_out(const std::vector<Sums>& sums, std::string& out) {
    out.resize(sums.size() * sizeof(Sums));
    if (!sums.empty()) std::memcpy(out.data(), sums.data(), out.size());
}

template <class Sums>
void copy_in(std::string_view bytes, std::vector<Sums>& out) {
    out.resize(bytes.size() / sizeof(Sums));
    if (!out.empty()) std::memcpy(out.data(), bytes.data(), out.size() * sizeof(Sums));
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

void write_records(const std::vector<PixelSums>& sums, std::string& out) {
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

void write_records(const std::vector<FirstHitSums>& sums, std::string& out) {
    out.resize(sums.size() * kFirstHitRecordBytes);
    char* at = out.data();
    for (const FirstHitSums& f : sums) {
        for (const double v : f.albedo) store(v, at);
        for (const double v : f.normal) store(v, at);
    }
}

void read_records(std::string_view bytes, std::vector<PixelSums>& out) {
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

void read_records(std::string_view bytes, std::vector<FirstHitSums>& out) {
    out.resize(bytes.size() / kFirstHitRecordBytes);
    const char* at = bytes.data();
    for (FirstHitSums& f : out) {
        for (double& v : f.albedo) v = load_double(at);
        for (double& v : f.normal) v = load_double(at);
    }
}

}  // namespace portable_records

void write_records(const std::vector<PixelSums>& sums, std::string& out) {
    if constexpr (kLittleEndian)
        copy_out(sums, out);
    else
        portable_records::write_records(sums, out);
}

void write_records(const std::vector<FirstHitSums>& sums, std::string& out) {
    if constexpr (kLittleEndian)
        copy_out(sums, out);
    else
        portable_records::write_records(sums, out);
}

void read_records(std::string_view bytes, std::vector<PixelSums>& out) {
    if constexpr (kLittleEndian)
        copy_in(bytes, out);
    else
        portable_records::read_records(bytes, out);
}

void read_records(std::string_view bytes, std::vector<FirstHitSums>& out) {
    if constexpr (kLittleEndian)
        copy_in(bytes, out);
    else
        portable_records::read_records(bytes, out);
}

}  // namespace aliquot
