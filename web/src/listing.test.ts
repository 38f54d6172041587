import { describe, expect, it } from "vitest";
import type { RenderSummary } from "./api";
import { matches, NO_FILTER, sortRenders, viewFromQuery } from "./listing";

function render(id: string, over: Partial<RenderSummary> = {}): RenderSummary {
  return {
    id,
    scene: "cornell-box",
    method: "uniform",
    state: "done",
    width: 8,
    height: 8,
    seed: "0",
    samples_done: 64,
    samples_planned: 64,
    rounds: 1,
    seconds: 1,
    samples_per_second: 64,
    error_estimate: 0.01,
    error_vs_reference: null,
    created_ms: Number(id.slice(2)) * 1000,
    progress: 1,
    ...over,
  };
}

const list = [
  render("r-3", { state: "queued", queue_position: 2, name: "Hero shot" }),
  render("r-2", { state: "running", progress: 0.5, samples_done: 32, samples_per_second: 16, method: "optimal" }),
  render("r-1", { scene: "sponza", error_estimate: null }),
  render("r-4", { state: "queued", queue_position: 1 }),
];

describe("filter", () => {
  it("by state, method, scene and part of the name or id", () => {
    expect(list.filter((r) => matches(r, { ...NO_FILTER, state: "queued" })).map((r) => r.id)).toEqual(["r-3", "r-4"]);
    expect(list.filter((r) => matches(r, { ...NO_FILTER, state: "active" })).length).toBe(3);
    expect(list.filter((r) => matches(r, { ...NO_FILTER, method: "optimal" })).map((r) => r.id)).toEqual(["r-2"]);
    expect(list.filter((r) => matches(r, { ...NO_FILTER, scene: "sponza" })).map((r) => r.id)).toEqual(["r-1"]);
    expect(list.filter((r) => matches(r, { ...NO_FILTER, text: "HERO" })).map((r) => r.id)).toEqual(["r-3"]);
    expect(list.filter((r) => matches(r, { ...NO_FILTER, text: "r-4" })).map((r) => r.id)).toEqual(["r-4"]);
    expect(list.filter((r) => matches(r, NO_FILTER)).length).toBe(4);
  });
});

describe("sort", () => {
  const ids = (rs: RenderSummary[]) => rs.map((r) => r.id);
  it("newest first by default, oldest first ascending", () => {
    expect(ids(sortRenders(list, "created", true))).toEqual(["r-4", "r-3", "r-2", "r-1"]);
    expect(ids(sortRenders(list, "created", false))).toEqual(["r-1", "r-2", "r-3", "r-4"]);
  });
  it("by state: the queue in its order, then running, then finished", () => {
    expect(ids(sortRenders(list, "state", false))).toEqual(["r-4", "r-3", "r-2", "r-1"]);
  });
  it("by name, an unnamed render by its id", () => {
    expect(ids(sortRenders(list, "name", false))).toEqual(["r-3", "r-1", "r-2", "r-4"]);
  });
  it("puts unknown values last whichever the direction", () => {
    expect(ids(sortRenders(list, "error", false)).at(-1)).toBe("r-1");
    expect(ids(sortRenders(list, "error", true)).at(-1)).toBe("r-1");
    expect(ids(sortRenders(list, "eta", false))[0]).toBe("r-2");
    expect(ids(sortRenders(list, "eta", true))[0]).toBe("r-2");
  });
  it("does not change its input", () => {
    const before = ids(list);
    sortRenders(list, "name", true);
    expect(ids(list)).toEqual(before);
  });
});

describe("the view in the address", () => {
  it("reads filter and sort, with newest first as the default", () => {
    const v = viewFromQuery(new URLSearchParams("state=done&method=uniform&q=hero&sort=eta&dir=asc"));
    expect(v.filter).toEqual({ state: "done", method: "uniform", scene: "", text: "hero" });
    expect(v.sort).toBe("eta");
    expect(v.descending).toBe(false);
    expect(viewFromQuery(new URLSearchParams("sort=bogus"))).toMatchObject({ sort: "created", descending: true });
  });
});
