// A render's state on the wire: the farm's RenderInfo to and from v1::RenderInfo. The
// gRPC server encodes with it and the CLI decodes with it, so both ends share one
// conversion.
#pragma once

#include "aliquot.pb.h"
#include "coordinator.h"
#include "wire.h"

namespace aliquot {

// The C++ side keeps its own RenderState (lifecycle/render_state.h) rather than using
// v1::RenderState: the store and the farm stay free of protobuf, and a switch over an
// enum class with no "unspecified" value is checked for completeness by the compiler.
// This is the one mapping between the two; it lives here, not in proto/wire, because
// RenderInfo belongs to the farm, which the worker's side of the wire must not see.
v1::RenderState to_proto(RenderState state);
// Throws WireError for RENDER_STATE_UNSPECIFIED or a value this build does not know.
RenderState from_proto(v1::RenderState state);

void to_proto(const RenderInfo& info, v1::RenderInfo& out);
// Throws WireError when the message carries no valid state.
RenderInfo from_proto(const v1::RenderInfo& in);

// A worker as ListWorkers sends it: `aliquot workers --json` prints it back through
// http_api::worker_json, the HTTP API's writer.
void to_proto(const WorkerStatus& worker, v1::WorkerInfo& out);
WorkerStatus from_proto(const v1::WorkerInfo& in);

// A render's event as GetEvents sends it (`aliquot logs` prints its kind and fields as
// they come: a newer coordinator's kinds included).
void to_proto(const RenderEvent& event, v1::RenderEvent& out);

}  // namespace aliquot
