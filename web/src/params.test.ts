import { describe, expect, it } from "vitest";
import type { MethodInfo } from "./api";
import { fieldSpecs, findMethod, paramSummary, strategyFromFields } from "./params";

// As GET /api/methods answers, cut down to two methods.
const METHODS: MethodInfo[] = [
  {
    name: "optimal",
    summary: "a pilot, then each pixel's samples in proportion to its noise",
    submittable: true,
    parameters: [
      { key: "spp", kind: "whole", default: 64, bounds: "a whole number from 0 to 4294967295", help: "samples per pixel", min: 0, max: 4294967295 },
      { key: "budget", kind: "whole", default: 0, bounds: "a whole number from 0 to 9007199254740992", help: "total samples", min: 0, max: 9007199254740992 },
      { key: "sigma_radius", kind: "whole", default: 0, bounds: "a whole number from 0 to 64", help: "pool radius", min: 0, max: 64 },
      {
        key: "floor_fraction",
        kind: "number",
        default: 0.5,
        bounds: "a number at least 0 and below 1",
        help: "pilot share",
        min: 0,
        max: 1,
        max_exclusive: true,
      },
    ],
  },
  {
    name: "dammertz",
    summary: "hierarchical buckets",
    submittable: true,
    parameters: [
      { key: "spp", kind: "whole", default: 0, bounds: "a whole number from 0 to 4294967295", help: "samples per pixel", min: 0, max: 4294967295 },
      { key: "error_norm", kind: "word", default: "seed", bounds: "seed or paper", help: "a bucket's error", values: ["seed", "paper"] },
    ],
  },
];

const optimal = findMethod(METHODS, "optimal")!;
const dammertz = findMethod(METHODS, "dammertz")!;

describe("the method's parameter fields", () => {
  it("are the chosen method's parameters only, with defaults and bounds", () => {
    const fields = fieldSpecs(optimal);
    expect(fields.map((f) => f.key)).toEqual(["spp", "budget", "sigma_radius", "floor_fraction"]);
    const radius = fields.find((f) => f.key === "sigma_radius")!;
    expect(radius.value).toBe("0");
    expect(radius.input).toEqual({ type: "number", step: "1", min: "0", max: "64" });
    expect(radius.title).toContain("a whole number from 0 to 64");
    // An exclusive end is left to the server, which names it.
    expect(fields.find((f) => f.key === "floor_fraction")!.input).toEqual({ type: "number", step: "any", min: "0" });
    expect(fieldSpecs(dammertz).map((f) => f.key)).toEqual(["spp", "error_norm"]);
  });
  it("offer a word's values as choices", () => {
    const norm = fieldSpecs(dammertz).find((f) => f.key === "error_norm")!;
    expect(norm.options).toEqual(["seed", "paper"]);
    expect(norm.value).toBe("seed");
  });
  it("hold a render's values when resubmitting", () => {
    expect(fieldSpecs(optimal, { spp: 0, budget: 5000 }).map((f) => f.value)).toEqual(["0", "5000", "0", "0.5"]);
  });
  it("send only what differs from the defaults", () => {
    expect(strategyFromFields(optimal, { spp: "64", budget: "0", sigma_radius: "2", floor_fraction: "0.5" })).toEqual({
      method: "optimal",
      sigma_radius: 2,
    });
    // A budget typed in and spp left at its default: spp is not sent beside it.
    expect(strategyFromFields(optimal, { spp: "64", budget: "100000", sigma_radius: "", floor_fraction: "0.5" })).toEqual({
      method: "optimal",
      budget: 100000,
    });
    expect(strategyFromFields(dammertz, { error_norm: "paper" })).toEqual({ method: "dammertz", error_norm: "paper" });
  });
});

describe("a render's parameters", () => {
  it("are its method's only, not every method's", () => {
    const strategy = { method: "optimal", spp: 64, budget: 0, sigma_radius: 0, floor_fraction: 0.5, alpha: 1, error_norm: "seed", noise_threshold: 0.01 };
    expect(paramSummary(optimal, strategy)).toBe("spp 64 · budget 0 · sigma radius 0 · floor fraction 0.5");
    expect(paramSummary(undefined, strategy)).toBe("");
  });
});
