// A render's trail of events: bounded however many rounds it has, numbered so that a
// reader sees what was dropped, one line per event in the log.
#include "render_events.h"

#include <gtest/gtest.h>

#include "render_queue.h"

namespace aliquot {
namespace {

TEST(RenderEvents, AFloodOfRoundsKeepsTheFirstAndTheLastOnly) {
    RenderEvents events;
    size_t lines = 0;
    events.log = [&](std::string_view, const LogFields&) { ++lines; };
    events.on_render(EventKind::Submitted, "r-1");
    for (int64_t round = 0; round < 100000; ++round)
        events.on_render(EventKind::RoundEnded, "r-1", {log_number("round", round)});
    events.on_render(EventKind::Finished, "r-1");
    EXPECT_EQ(lines, 100002u);  // the log has every one
    const EventPage page = *events.read("r-1", -1, 1000);
    ASSERT_EQ(page.events.size(), RenderEvents::kKeepFirst + RenderEvents::kKeepLast);
    EXPECT_EQ(page.omitted, 100002u - page.events.size());
    EXPECT_EQ(page.events.front().kind, EventKind::Submitted);
    EXPECT_EQ(page.events.back().kind, EventKind::Finished);
    EXPECT_EQ(page.events.back().seq, 100001u);
    // A reader following the render asks after the last it saw.
    EXPECT_EQ(events.read("r-1", 100000, 1000)->events.size(), 1u);
    EXPECT_EQ(events.read("r-1", -1, 3)->events.size(), 3u);
}

TEST(RenderEvents, AnUnknownRenderHasNoEventsAndForgettingFreesTheTrail) {
    RenderEvents events;
    events.log = [](std::string_view, const LogFields&) {};
    EXPECT_FALSE(events.read("r-404", -1, 10));
    events.on_render(EventKind::Submitted, "r-1");
    EXPECT_EQ(events.trails(), 1u);
    events.forget("r-1");
    EXPECT_EQ(events.trails(), 0u);
    EXPECT_FALSE(events.read("r-1", -1, 10));
}

TEST(RenderEvents, WorkerEventsAreLoggedNotKept) {
    RenderEvents events;
    std::string seen;
    events.log = [&](std::string_view event, const LogFields& fields) {
        seen = format_log_line(LogFormat::Json, 0, event, fields);
    };
    events.on_worker(EventKind::WorkerLost, "w\n1");
    EXPECT_EQ(seen,
              "{\"time\":\"1970-01-01T00:00:00.000Z\",\"event\":\"worker_lost\","
              "\"worker\":\"w\\n1\"}");
    EXPECT_EQ(events.trails(), 0u);
}

TEST(RenderEvents, EveryKindHasOneSpellingThatReadsBack) {
    for (int k = 0; k <= int(EventKind::WorkerBlocklisted); ++k) {
        const EventKind kind = EventKind(k);
        EXPECT_EQ(parse_event_kind(to_string(kind)), kind) << to_string(kind);
    }
    EXPECT_FALSE(parse_event_kind("exploded"));
}

TEST(RenderQueue, PositionsFollowPriorityThenSubmission) {
    RenderQueue q;
    q.add("a", 0, 0);
    q.add("b", 0, 1);
    q.add("c", 5, 2);
    EXPECT_EQ(q.position("c"), 1u);
    EXPECT_EQ(q.position("a"), 2u);
    EXPECT_EQ(q.position("b"), 3u);
    q.set_priority("b", 9);
    EXPECT_EQ(q.position("b"), 1u);
    q.set_priority("b", 0);  // back behind a, which came first
    EXPECT_EQ(q.position("b"), 3u);
    EXPECT_TRUE(q.leave("c"));
    EXPECT_FALSE(q.leave("c"));
    EXPECT_EQ(q.position("c"), 0u);
    EXPECT_EQ(q.position("a"), 1u);
    q.set_priority("zzz", 3);  // not queued: nothing
    EXPECT_EQ(q.size(), 2u);
}

}  // namespace
}  // namespace aliquot
