import { describe, expect, it } from "vitest";
import { colorize, decodeBase64, SPP_MAP } from "./colormap";
import * as fmt from "./format";

describe("format", () => {
  it("abbreviates counts", () => {
    expect(fmt.count(999)).toBe("999");
    expect(fmt.count(12_345)).toBe("12.3k");
    expect(fmt.count(2_500_000)).toBe("2.50M");
    expect(fmt.count(NaN)).toBe("–");
  });
  it("shows errors with three significant digits and null as a dash", () => {
    expect(fmt.error(0.012345)).toBe("0.0123");
    expect(fmt.error(0.00012345)).toBe("1.23e-4");
    expect(fmt.error(null)).toBe("–");
  });
  it("says how long ago", () => {
    expect(fmt.ago(10_000, 10_500)).toBe("just now");
    expect(fmt.ago(10_000, 15_000)).toBe("5 s ago");
    expect(fmt.ago(0, 15_000)).toBe("never");
  });
  it("clamps percentages", () => {
    expect(fmt.percent(1.2)).toBe("100 %");
    expect(fmt.percent(0.456)).toBe("45 %");
  });
});

describe("colormap", () => {
  it("decodes base64 map bytes and colours them through the table", () => {
    const bytes = decodeBase64("AP8="); // [0, 255]
    expect([...bytes]).toEqual([0, 255]);
    const rgba = colorize(bytes, SPP_MAP);
    expect(rgba.length).toBe(8);
    expect([...rgba.slice(0, 3)]).toEqual([...SPP_MAP.slice(0, 3)]);
    expect([...rgba.slice(4, 7)]).toEqual([...SPP_MAP.slice(255 * 3, 255 * 3 + 3)]);
    expect(rgba[3]).toBe(255);
  });
});
