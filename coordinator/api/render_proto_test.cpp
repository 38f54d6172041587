// The wire's enums and the farm's RenderInfo survive a round trip, and a value the reader
// does not know is an error (a state) or counts nothing (a completion status).
#include "render_proto.h"

#include <gtest/gtest.h>

namespace aliquot {
namespace {

TEST(RenderProto, EveryRenderStateRoundTrips) {
    for (RenderState s : {RenderState::Queued, RenderState::Running, RenderState::Done,
                          RenderState::Cancelled, RenderState::Failed}) {
        EXPECT_NE(to_proto(s), v1::RENDER_STATE_UNSPECIFIED);
        EXPECT_EQ(from_proto(to_proto(s)), s);
    }
}

TEST(RenderProto, AnUnspecifiedOrUnknownStateIsAWireError) {
    EXPECT_THROW(from_proto(v1::RENDER_STATE_UNSPECIFIED), WireError);
    EXPECT_THROW(from_proto(v1::RenderState(99)), WireError);
    EXPECT_THROW(from_proto(v1::RenderInfo{}), WireError);
}

TEST(RenderProto, RenderInfoRoundTripsFieldForField) {
    RenderInfo a;
    a.id = "r-000007";
    a.scene_name = "cornell-box";
    a.method = "dammertz";
    a.strategy_json = R"({"method":"dammertz"})";
    a.state = RenderState::Cancelled;
    a.error = "stopped";
    a.outcome_json = R"({"max_spp":0.1})";
    a.width = 48;
    a.height = 40;
    a.seed = 7;
    a.samples_done = 30720;
    a.samples_planned = 40000;
    a.rays = 158492;
    a.rounds_done = 5;
    a.seconds = 0.5;
    a.samples_per_second = 61440;
    a.error_estimate = 0.015;
    a.error_vs_reference = -1;
    a.created_ms = 1700000000000;
    a.finished_ms = 1700000000500;
    v1::RenderInfo message;
    to_proto(a, message);
    const RenderInfo b = from_proto(message);
    v1::RenderInfo again;
    to_proto(b, again);
    EXPECT_EQ(b.state, RenderState::Cancelled);
    EXPECT_EQ(again.SerializeAsString(), message.SerializeAsString());
}

TEST(CompleteStatusWire, RoundTripsAndReadsUnknownAsIgnored) {
    for (CompleteStatus s :
         {CompleteStatus::Merged, CompleteStatus::Ignored, CompleteStatus::Rejected})
        EXPECT_EQ(from_proto(to_proto(s)), s);
    EXPECT_EQ(from_proto(v1::COMPLETE_STATUS_UNSPECIFIED), CompleteStatus::Ignored);
    EXPECT_EQ(from_proto(v1::CompleteStatus(42)), CompleteStatus::Ignored);
}

}  // namespace
}  // namespace aliquot
