import { describe, expect, it } from "vitest";
import { etaSeconds, etaText } from "./eta";

const running = {
  state: "running" as const,
  method: "uniform",
  samples_done: 100,
  samples_planned: 400,
  samples_per_second: 50,
  seconds: 2,
  progress: 0.25,
};

describe("eta", () => {
  it("is the samples left at the measured rate, as the CLI says", () => {
    expect(etaSeconds(running)).toBe(6);
  });
  it("goes by progress for Dammertz and bucket methods, whose plan is only a cap", () => {
    expect(etaSeconds({ ...running, method: "dammertz", samples_planned: 1e9 })).toBe(6);
    expect(etaSeconds({ ...running, method: "adaptive", buckets_total: 12, progress: 0.5, seconds: 10 })).toBe(10);
  });
  it("is unknown before anything merged, without a rate, and when not running", () => {
    expect(etaSeconds({ ...running, samples_done: 0 })).toBeNull();
    expect(etaSeconds({ ...running, samples_per_second: 0, progress: 0 })).toBeNull();
    expect(etaSeconds({ ...running, state: "done" })).toBeNull();
    expect(etaSeconds({ ...running, state: "queued" })).toBeNull();
  });
  it("says a queued render's place in the queue", () => {
    const s = (x: number) => `${x} s`;
    expect(etaText({ ...running, state: "queued", samples_done: 0, queue_position: 2 }, s)).toBe("queued #2");
    expect(etaText(running, s)).toBe("6 s");
    expect(etaText({ ...running, state: "done" }, s)).toBe("–");
  });
});
