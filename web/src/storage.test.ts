import { describe, expect, it } from "vitest";
import { StorageBanner } from "./storage";

describe("StorageBanner", () => {
  it("shows the server's storage warning and hides once it clears", () => {
    const el = { hidden: false, textContent: "" as string | null };
    const banner = new StorageBanner(el);
    expect(el.hidden).toBe(true);

    banner.onEvent({ type: "hello", now_ms: 1, storage_warning: "cannot record round 3 of r-000001: database or disk is full" });
    expect(el.hidden).toBe(false);
    expect(el.textContent).toContain("cannot write its record");
    expect(el.textContent).toContain("database or disk is full");

    banner.onEvent({ type: "render", renders: [] }); // other events leave it alone
    expect(el.hidden).toBe(false);

    banner.onEvent({ type: "storage", storage_warning: "" });
    expect(el.hidden).toBe(true);
    expect(el.textContent).toBe("");

    banner.onEvent({ type: "storage", storage_warning: "cannot record the end of r-000002: No space left on device" });
    expect(el.hidden).toBe(false);
    banner.onEvent({ type: "hello", now_ms: 2 }); // an older server's greeting: no warning
    expect(el.hidden).toBe(true);
  });
});
