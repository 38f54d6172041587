// The fixed little-endian records a SampleJobResult carries a job's sums in
// (aliquot.proto, wire version 2): on a little-endian machine each array is its bytes,
// one copy each way; on any other, the same bytes written and read field by field.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "sample_job.h"

namespace aliquot {

inline constexpr size_t kPixelRecordBytes = 80;     // PixelSums: 7 binary64, 3 uint64
inline constexpr size_t kFirstHitRecordBytes = 48;  // FirstHitSums: 6 binary64

// `out` becomes the records of `sums`, in their order.
void write_records(const SumsArray<PixelSums>& sums, std::string& out);
void write_records(const SumsArray<FirstHitSums>& sums, std::string& out);
// `out` becomes the sums `bytes` holds, copied: its size must be a whole number of
// records (the caller checks it against the rect: wire.cpp).
void read_records(std::string_view bytes, SumsArray<PixelSums>& out);
void read_records(std::string_view bytes, SumsArray<FirstHitSums>& out);
// The same, but read where `bytes` holds them, which must then stay, unchanged, while
// `out` is read: no copy, where the bytes are the struct's (a little-endian machine) and
// aligned for it; copied otherwise.
void read_records_in_place(std::string_view bytes, SumsArray<PixelSums>& out);
void read_records_in_place(std::string_view bytes, SumsArray<FirstHitSums>& out);

// Field by field, whatever the machine's byte order: what the four above do on a
// big-endian one, here so that a test on a little-endian one checks both agree.
namespace portable_records {
void write_records(const SumsArray<PixelSums>& sums, std::string& out);
void write_records(const SumsArray<FirstHitSums>& sums, std::string& out);
void read_records(std::string_view bytes, SumsArray<PixelSums>& out);
void read_records(std::string_view bytes, SumsArray<FirstHitSums>& out);
}  // namespace portable_records

}  // namespace aliquot
