// Conversions between sample jobs / results and their protobuf messages. Decoding checks
// array lengths, so a malformed message is an error, never an out-of-bounds read.
#pragma once

#include <stdexcept>

#include "aliquot.pb.h"
#include "sample_job.h"

namespace aliquot {

class WireError : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

void to_proto(const SampleJob& job, v1::SampleJob& out);
SampleJob from_proto(const v1::SampleJob& in);
void to_proto(const SampleJobResult& result, v1::SampleJobResult& out);
SampleJobResult from_proto(const v1::SampleJobResult& in);

}  // namespace aliquot
