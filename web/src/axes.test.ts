import { describe, expect, it } from "vitest";
import { legendValue, logRange, logSplits, pilotRounds, pilotSamples, positiveExtent } from "./axes";

describe("axes fitted to the render", () => {
  it("a 268 M-sample, 140 s render is not drawn to 1 G samples and 16 minutes", () => {
    const [lo, hi] = logRange(2e6, 268e6);
    expect(hi).toBeGreaterThan(268e6);
    expect(hi).toBeLessThan(400e6);
    expect(lo).toBeLessThan(2e6);
    expect(lo).toBeGreaterThan(1e6);
    const [, t] = logRange(3, 140);
    expect(t).toBeGreaterThan(140);
    expect(t).toBeLessThan(200);
  });
  it("gives one point or a flat curve an axis around it", () => {
    const [lo, hi] = logRange(50, 50);
    expect(lo).toBeLessThan(50);
    expect(hi).toBeGreaterThan(50);
    expect(Math.log10(hi / lo)).toBeGreaterThanOrEqual(0.3 - 1e-9);
  });
  it("survives nothing to show", () => {
    expect(logRange(0, 0)).toEqual([1, 10]);
    expect(logRange(NaN, 5)).toEqual([1, 10]);
    expect(positiveExtent([null, 0, -1], [])).toBeNull();
    expect(positiveExtent([3, null, 1], [7, NaN])).toEqual([1, 7]);
  });
});

describe("the pilot", () => {
  const optimal = { method: "optimal", width: 96, height: 96, samples_planned: 589824, strategy: { spp: 64, budget: 0, min_spp: 4, floor_fraction: 0.5 } };
  it("is half the budget by default", () => {
    expect(pilotSamples(optimal)).toBe(32 * 96 * 96);
  });
  it("is at least min_spp a pixel, and only the optimal methods have one", () => {
    expect(pilotSamples({ ...optimal, strategy: { spp: 64, min_spp: 8, floor_fraction: 0 } })).toBe(8 * 96 * 96);
    expect(pilotSamples({ ...optimal, method: "uniform" })).toBeNull();
  });
  it("covers the leading rounds that end within it (a split pilot is two)", () => {
    // The probe render of issue 32: rounds of 147456, 147456, 147456, 73728, ...
    expect(pilotRounds([147456, 294912, 442368, 516096], 294912)).toBe(2);
    expect(pilotRounds([147456], null)).toBe(0);
  });
});

describe("log ticks", () => {
  it("are 1, 2, 5 per decade over a fitted range, a bounded number however wide", () => {
    // Less than a decade: every digit.
    expect(logSplits(0.0054, 0.0153)).toEqual([0.006, 0.007, 0.008, 0.009, 0.01]);
    // Where even the digits are few, they are what there is; an axis narrower than a digit has its ends.
    expect(logSplits(0.0708, 0.141)).toEqual([0.08, 0.09, 0.1]);
    expect(logSplits(3, 140)).toEqual([5, 10, 20, 50, 100]);
    expect(logSplits(0.95, 1.05)).toEqual([0.95, 1.05]);
    expect(logSplits(1e-300, 1e300).length).toBeLessThanOrEqual(12);
    expect(logSplits(1e-300, 1e300).length).toBeGreaterThanOrEqual(2);
    for (const [lo, hi] of [[655.36, 86390], [0.07, 4.3], [1.5e6, 3.9e8], [2.2e-5, 3e-3]] as const) {
      const s = logSplits(lo, hi);
      expect(s.length).toBeGreaterThanOrEqual(2);
      expect(s.length).toBeLessThanOrEqual(12);
      for (const v of s) expect(v >= lo && v <= hi).toBe(true);
    }
  });
  it("never loop or fail on nothing to show", () => {
    expect(logSplits(0, 10)).toEqual([]);
    expect(logSplits(5, 5)).toEqual([5]);
    expect(logSplits(NaN, 1)).toEqual([]);
  });
});

describe("legends", () => {
  const f = (v: number) => v.toFixed(1);
  it("show the hovered value, blank where the series has none, the latest when nothing is hovered", () => {
    expect(legendValue([1, null, 3], 0, f)).toBe("1.0");
    expect(legendValue([1, null, 3], 1, f)).toBe("");
    expect(legendValue([1, 3, null], null, f)).toBe("3.0");
    expect(legendValue([], undefined, f)).toBe("");
    expect(legendValue([null], null, f)).not.toBe("--");
  });
});
