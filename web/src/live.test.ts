import { afterEach, describe, expect, it, vi } from "vitest";
import { throttle } from "./live";

describe("throttle", () => {
  afterEach(() => vi.useRealTimers());
  it("runs at once, then folds calls within the interval into one trailing run", () => {
    vi.useFakeTimers();
    let runs = 0;
    const t = throttle(() => runs++, 1000);
    t();
    expect(runs).toBe(1);
    t();
    t();
    t();
    expect(runs).toBe(1);
    vi.advanceTimersByTime(999);
    expect(runs).toBe(1);
    vi.advanceTimersByTime(1);
    expect(runs).toBe(2);
    vi.advanceTimersByTime(5000);
    expect(runs).toBe(2);
  });
});
