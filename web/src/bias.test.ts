import { describe, expect, it } from "vitest";
import { roundFromRow } from "./api";
import { biasBeyondNoise, biasText } from "./bias";

describe("mean bias", () => {
  it("says a bias with its standard error and marks one beyond 3 SE", () => {
    expect(biasText(-0.0491, 0.0012)).toBe("-4.91 % ± 0.12 %, beyond 3 SE");
    expect(biasBeyondNoise(-0.0491, 0.0012)).toBe(true);
    expect(biasText(0.001, 0.002)).toBe("+0.1 % ± 0.2 %");
    expect(biasBeyondNoise(0.001, 0.002)).toBe(false);
    expect(biasText(-0.05, 0)).toBe("-5 % ± 0 %, beyond 3 SE"); // every block alike
  });
  it("shows a dash without a bias and no SE without one", () => {
    expect(biasText(null, null)).toBe("–");
    expect(biasText(undefined, undefined)).toBe("–"); // an older coordinator's render
    expect(biasText(NaN, 0.01)).toBe("–");
    expect(biasText(-0.02, null)).toBe("-2 %");
    expect(biasBeyondNoise(-0.02, null)).toBe(false);
    expect(biasBeyondNoise(null, 0.01)).toBe(false);
  });
});

describe("round rows", () => {
  it("reads the bias columns, and an older coordinator's rows without them", () => {
    expect(roundFromRow([3, 100, 400, 1.5, 0.02, 0.03, -0.0491, 0.0012])).toEqual({
      index: 3,
      samples_in_round: 100,
      samples_total: 400,
      seconds: 1.5,
      error_estimate: 0.02,
      error_vs_reference: 0.03,
      mean_bias: -0.0491,
      mean_bias_se: 0.0012,
    });
    const old = roundFromRow([0, 100, 100, 0.5, 0.02, null]);
    expect(old.mean_bias).toBeNull();
    expect(old.mean_bias_se).toBeNull();
    expect(roundFromRow([0, 100, 100, 0.5, 0.02, 0.03, null, null]).mean_bias).toBeNull();
  });
});
