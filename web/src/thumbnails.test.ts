import { describe, expect, it } from "vitest";
import { ThumbnailSchedule } from "./thumbnails";

describe("thumbnail schedule", () => {
  it("fetches when the samples change, at most every interval", () => {
    const s = new ThumbnailSchedule(3000);
    expect(s.wait(0, 0)).toBeNull(); // nothing traced yet
    expect(s.wait(10, 0)).toBe(0);
    s.fetching(10, 0);
    s.loaded();
    expect(s.wait(10, 5000)).toBeNull();
    expect(s.wait(20, 1000)).toBe(2000);
  });

  // Review of issue 32: a thumbnail refused with 503 stayed broken, its samples counted as
  // shown, and nothing fetched it again.
  it("fetches again after a failed load, waiting longer each time", () => {
    const s = new ThumbnailSchedule(3000, 10_000);
    s.fetching(10, 0);
    s.failed();
    expect(s.wait(10, 0)).toBe(6000);
    s.fetching(10, 6000);
    s.failed();
    expect(s.wait(10, 6000)).toBe(10_000); // capped
    s.fetching(10, 16_000);
    s.loaded();
    expect(s.wait(10, 20_000)).toBeNull();
    expect(s.wait(11, 20_000)).toBe(0);
  });
});
