#include "wire.h"

#include <string>
#include <string_view>

#include "sum_records.h"

namespace aliquot {

namespace {

void to_proto(const PixelRect& r, v1::PixelRect& out) {
    out.set_x(r.x);
    out.set_y(r.y);
    out.set_width(r.width);
    out.set_height(r.height);
}

PixelRect from_proto(const v1::PixelRect& r) {
    // Bounded so that width * height cannot overflow and a message cannot ask for a
    // rectangle larger than any image.
    if (r.width() > 65536 || r.height() > 65536)
        throw WireError("rectangle " + std::to_string(r.width()) + "x" +
                        std::to_string(r.height()) + " is too large");
    return {r.x(), r.y(), r.width(), r.height()};
}

void expect_size(const char* field, size_t got, size_t want) {
    if (got != want)
        throw WireError(std::string(field) + " has " + std::to_string(got) +
                        " values, expected " + std::to_string(want));
}

// `field` must hold exactly `n` records of `record` bytes each (the division, not n times
// the record, so that no size overflows).
void expect_records(const char* field, size_t bytes, size_t record, size_t n) {
    if (bytes % record != 0 || bytes / record != n)
        throw WireError(std::string(field) + " has " + std::to_string(bytes) +
                        " bytes, expected " + std::to_string(n) + " records of " +
                        std::to_string(record));
}

}  // namespace

void to_proto(const SampleJob& job, v1::SampleJob& out) {
    to_proto(job.rect, *out.mutable_rect());
    out.mutable_counts()->Assign(job.counts.begin(), job.counts.end());
    out.mutable_first_sample()->Assign(job.first_sample.begin(), job.first_sample.end());
    out.set_aux(job.aux);
}

SampleJob from_proto(const v1::SampleJob& in) {
    SampleJob job;
    job.rect = from_proto(in.rect());
    expect_size("counts", size_t(in.counts_size()), job.rect.size());
    expect_size("first_sample", size_t(in.first_sample_size()), job.rect.size());
    job.counts.assign(in.counts().begin(), in.counts().end());
    job.first_sample.assign(in.first_sample().begin(), in.first_sample().end());
    job.aux = in.aux();
    return job;
}

void to_proto(const SampleJobResult& result, v1::SampleJobResult& out) {
    to_proto(result.rect, *out.mutable_rect());
    write_records(result.pixels, *out.mutable_pixels());
    if (!result.first_hits.empty())
        write_records(result.first_hits, *out.mutable_first_hits());
    out.set_wall_seconds(result.wall_seconds);
    out.set_version(kWireVersion);
}

namespace {

// The checks both decodes make, then `read` (a copy, or in place) of each array.
template <class Read>
void decode(const v1::SampleJobResult& in, SampleJobResult& out, Read read) {
    if (in.version() != kWireVersion)
        throw WireError("result of wire protocol version " +
                        std::to_string(in.version()) +
                        ", this coordinator speaks version " +
                        std::to_string(kWireVersion) + ": update the worker");
    out.rect = from_proto(in.rect());
    // Only sizes are checked here, before anything is read or allocated: what the sums
    // say (finite, the job's counts, zero where untraced) is the Accumulator's to check,
    // as for a result that never met the wire.
    const size_t n = out.rect.size();
    expect_records("pixels", in.pixels().size(), kPixelRecordBytes, n);
    // Whether the job asked for them is the coordinator's to check (AuxSums): here they
    // are whole, or absent.
    if (!in.first_hits().empty())
        expect_records("first_hits", in.first_hits().size(), kFirstHitRecordBytes, n);
    read(in.pixels(), out.pixels);
    if (in.first_hits().empty())
        out.first_hits.clear();
    else
        read(in.first_hits(), out.first_hits);
    out.wall_seconds = in.wall_seconds();
}

}  // namespace

SampleJobResult from_proto(const v1::SampleJobResult& in) {
    SampleJobResult result;
    decode(in, result,
           [](std::string_view bytes, auto& sums) { read_records(bytes, sums); });
    return result;
}

void from_proto_in_place(const v1::SampleJobResult& in, SampleJobResult& out) {
    decode(in, out, [](std::string_view bytes, auto& sums) {
        read_records_in_place(bytes, sums);
    });
}

v1::CompleteStatus to_proto(CompleteStatus status) {
    switch (status) {
        case CompleteStatus::Merged:
            return v1::COMPLETE_STATUS_MERGED;
        case CompleteStatus::Ignored:
            return v1::COMPLETE_STATUS_IGNORED;
        case CompleteStatus::Rejected:
            return v1::COMPLETE_STATUS_REJECTED;
    }
    return v1::COMPLETE_STATUS_UNSPECIFIED;
}

CompleteStatus from_proto(v1::CompleteStatus status) {
    switch (status) {
        case v1::COMPLETE_STATUS_MERGED:
            return CompleteStatus::Merged;
        case v1::COMPLETE_STATUS_REJECTED:
            return CompleteStatus::Rejected;
        default:
            return CompleteStatus::Ignored;
    }
}

}  // namespace aliquot
