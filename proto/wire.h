// Conversions between sample jobs / results / completion statuses and their protobuf
// messages. Decoding checks array and record lengths, so a malformed message is an error,
// never an out-of-bounds read.
#pragma once

#include <stdexcept>

#include "aliquot.pb.h"
#include "lease.h"
#include "sample_job.h"

namespace aliquot {

class WireError : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

// The version of the job and result messages this build speaks, carried in every
// result (SampleJobResult.version) and checked by from_proto: a result of another version
// is a WireError, so it is refused whole. 1 added the first-hit sums (issue 34); a worker
// from before sends none (0). 2 carries a result's sums as fixed little-endian records in
// two bytes fields (sum_records.h), decoded with a length check and one copy (issue 33).
inline constexpr uint32_t kWireVersion = 2;

void to_proto(const SampleJob& job, v1::SampleJob& out);
SampleJob from_proto(const v1::SampleJob& in);
void to_proto(const SampleJobResult& result, v1::SampleJobResult& out);
SampleJobResult from_proto(const v1::SampleJobResult& in);
// `out` becomes `in`'s result, its sums read where `in`'s bytes hold them
// (sum_records.h's read_records_in_place), with the same checks: what Complete merges,
// with no copy of the sums. `in` must outlive every read of `out` unchanged; a copy or a
// move of `out` owns its sums (SumsArray), so pass it on by reference.
void from_proto_in_place(const v1::SampleJobResult& in, SampleJobResult& out);

// The worker loop and the coordinator speak the C++ CompleteStatus (worker/job/lease.h):
// the embedded render passes it by direct call, with no protobuf in between. These two
// are the only place it meets v1::CompleteStatus. An unspecified or unknown status reads
// as Ignored, which counts nothing and sends nothing again.
v1::CompleteStatus to_proto(CompleteStatus status);
CompleteStatus from_proto(v1::CompleteStatus status);

}  // namespace aliquot
