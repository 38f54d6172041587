import { describe, expect, it } from "vitest";
import { eventLines } from "./events";

describe("a render's events as log lines", () => {
  it("takes time, kind and the other fields, flat or nested", () => {
    const lines = eventLines({
      events: [
        { seq: 0, time_ms: 1000, event: "submitted", render: "r-1", name: "hero shot" },
        { seq: 1, time: "2026-12-04T12:42:16.123Z", kind: "round_ended", fields: { round: 3, samples: 1024 } },
      ],
    });
    expect(lines[0]).toEqual({ timeMs: 1000, kind: "submitted", detail: 'name="hero shot"' });
    expect(lines[1].timeMs).toBe(Date.parse("2026-12-04T12:42:16.123Z"));
    expect(lines[1].kind).toBe("round_ended");
    expect(lines[1].detail).toBe("round=3 samples=1024");
  });
  it("reads the coordinator's own shape (docs/API.md, GET /api/renders/{id}/events)", () => {
    const lines = eventLines({
      id: "r-1",
      events: [{ seq: 2, at_ms: 5000, kind: "round_ended", fields: { round: 0, samples: 262144 } }],
      omitted: 0,
      next: 3,
    });
    expect(lines).toEqual([{ timeMs: 5000, kind: "round_ended", detail: "round=0 samples=262144" }]);
  });
  it("accepts a bare list and ignores what is not a list of objects", () => {
    expect(eventLines([{ type: "finished" }])).toEqual([{ timeMs: null, kind: "finished", detail: "" }]);
    expect(eventLines({ events: "nope" })).toEqual([]);
    expect(eventLines(null)).toEqual([]);
    expect(eventLines([null, 3])).toEqual([]);
  });
});
