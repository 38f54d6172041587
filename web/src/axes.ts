// Chart ranges fitted to the render: uPlot's own log scales snap to whole decades, which
// drew a 268 M-sample, 140 s render on axes running to 1 G samples and 16 minutes. And the
// optimal methods' pilot, which is half the budget by default: where it ends, so that the
// charts can show it while it runs.
import type { RenderDetail } from "./api";

/**
 * A log-scale range around [lo, hi] with `pad` of the span (in decades) on each side and
 * at least `minDecades` in all, so one point or a flat curve still gets an axis.
 */
export function logRange(lo: number, hi: number, pad = 0.06, minDecades = 0.3): [number, number] {
  if (!(lo > 0) || !(hi > 0) || !Number.isFinite(lo) || !Number.isFinite(hi)) return [1, 10];
  if (lo > hi) [lo, hi] = [hi, lo];
  let a = Math.log10(lo);
  let b = Math.log10(hi);
  if (b - a < minDecades) {
    const mid = (a + b) / 2;
    a = mid - minDecades / 2;
    b = mid + minDecades / 2;
  }
  const p = (b - a) * pad;
  return [10 ** (a - p), 10 ** (b + p)];
}

/** The smallest and largest positive finite values, or null when there is none. */
export function positiveExtent(...lists: (number | null | undefined)[][]): [number, number] | null {
  let lo = Infinity;
  let hi = -Infinity;
  for (const list of lists)
    for (const v of list)
      if (v !== null && v !== undefined && Number.isFinite(v) && v > 0) {
        lo = Math.min(lo, v);
        hi = Math.max(hi, v);
      }
  return lo <= hi ? [lo, hi] : null;
}

/**
 * The samples the pilot of an `optimal` or `optimal-time` render traces
 * (docs/STRATEGIES.md: `max(min_spp, ⌊floor_fraction × budget / pixels⌋)` a pixel), or
 * null for other methods.
 */
export function pilotSamples(r: Pick<RenderDetail, "method" | "width" | "height" | "strategy" | "samples_planned">): number | null {
  if (r.method !== "optimal" && r.method !== "optimal-time") return null;
  const s = r.strategy ?? {};
  const pixels = r.width * r.height;
  if (!pixels) return null;
  const num = (k: string, d: number) => (typeof s[k] === "number" ? (s[k] as number) : d);
  const budget = num("budget", 0) || num("spp", 0) * pixels || r.samples_planned;
  if (!budget) return null;
  const spp = Math.max(num("min_spp", 4), Math.floor((num("floor_fraction", 0.5) * budget) / pixels));
  return Math.min(budget, spp * pixels);
}

/** How many of the leading rounds are the pilot's: those that end within its samples. */
export function pilotRounds(totals: number[], pilot: number | null): number {
  if (!pilot) return 0;
  let n = 0;
  while (n < totals.length && totals[n] <= pilot) n++;
  return n;
}

/**
 * A legend's text for series `s` at data index `idx`: the hovered point's value, blank
 * where this series has none there (another curve's point), and the latest value when
 * nothing is hovered; never uPlot's "--".
 */
export function legendValue(column: (number | null | undefined)[], idx: number | null | undefined, format: (v: number) => string): string {
  if (idx === null || idx === undefined) {
    for (let i = column.length - 1; i >= 0; i--) {
      const v = column[i];
      if (v !== null && v !== undefined) return format(v);
    }
    return "";
  }
  const v = column[idx];
  return v === null || v === undefined ? "" : format(v);
}

/**
 * Tick values of a log axis over [lo, hi]: 1, 2 and 5 times powers of ten, fewer when the
 * range spans many decades, and the ends themselves when fewer than two fall inside.
 * uPlot's own log splits assume a range that starts on a power of ten (its default
 * ranges do); over a range fitted to the data they could loop until the array overflowed.
 */
export function logSplits(lo: number, hi: number, maxTicks = 8): number[] {
  if (!(lo > 0) || !(hi > lo) || !Number.isFinite(hi)) return lo > 0 && Number.isFinite(lo) ? [lo] : [];
  const first = Math.floor(Math.log10(lo));
  const last = Math.ceil(Math.log10(hi));
  const ticks = (steps: number[], every = 1) => {
    const out: number[] = [];
    for (let e = first; e <= last; e += every)
      for (const m of steps) {
        const v = Number((m * 10 ** e).toPrecision(12));
        if (v >= lo && v <= hi) out.push(v);
      }
    return out;
  };
  const nice = ticks([1, 2, 5]);
  if (nice.length >= 3 && nice.length <= maxTicks) return nice;
  if (nice.length < 3) {
    // Less than a decade: every digit, so the axis still has a few labels.
    const dense = ticks([1, 2, 3, 4, 5, 6, 7, 8, 9]);
    if (dense.length >= 2 && dense.length <= maxTicks) return dense;
    return nice.length >= 2 ? nice : [lo, hi];
  }
  // Many decades: every n-th power of ten.
  const every = Math.ceil((last - first + 1) / maxTicks);
  const sparse = ticks([1], every);
  return sparse.length >= 2 ? sparse : [lo, hi];
}
