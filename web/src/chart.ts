// Error curves drawn with uPlot: one chart per view, resized with its container, data
// replaced as rounds arrive. The number of points drawn is kept in data-points so the
// end-to-end test can check that every round added one.
import uPlot from "uplot";
import "uplot/dist/uPlot.min.css";
import { legendValue, logRange, logSplits, positiveExtent } from "./axes";
import * as fmt from "./format";

export interface SeriesSpec {
  label: string;
  color: string;
  dash?: number[];
}

export interface ChartSpec {
  title: string;
  xLabel: string;
  yLabel: string;
  series: SeriesSpec[];
  logX?: boolean;
  logY?: boolean;
  height?: number;
}

export const PALETTE = ["#2f6fdf", "#e4572e", "#17a589", "#a05ad6", "#f0a202", "#d6336c", "#5c7080", "#6cbf3a"];

const positive = (v: number | null | undefined): number | null =>
  v !== null && v !== undefined && Number.isFinite(v) && v > 0 ? v : null;

/** What a chart shows besides its points: values its x axis must reach, the pilot, now. */
export interface ChartView {
  /** x values the axis includes: the planned samples, the expected end. */
  xInclude?: number[];
  /** The pilot's span on the x axis, shaded and labelled. */
  pilot?: [number, number] | null;
  /** Where the render is now (a dashed line): it moves while a long round runs. */
  now?: number | null;
}


export class ErrorChart {
  readonly el: HTMLDivElement;
  private plot: uPlot | null = null;
  private observer: ResizeObserver;
  private spec: ChartSpec;
  private data: uPlot.AlignedData = [[]];
  private view: ChartView = {};

  constructor(spec: ChartSpec) {
    this.spec = spec;
    this.el = document.createElement("div");
    this.el.className = "chart";
    this.el.dataset.points = "0";
    this.observer = new ResizeObserver(() => this.resize());
    this.observer.observe(this.el);
  }

  /** Series of (x, y) pairs per series; non-positive values are left out (log scales). */
  setSeries(series: { x: number[]; y: (number | null)[] }[], spec?: Partial<ChartSpec>, view?: ChartView): void {
    if (view) this.view = view;
    if (spec) {
      this.spec = { ...this.spec, ...spec };
      this.plot?.destroy();
      this.plot = null;
    }
    const tables: uPlot.AlignedData[] = series.map((s) => {
      const pairs = s.x
        .map((x, i) => [positive(x), positive(s.y[i])] as const)
        .filter((p): p is readonly [number, number] => p[0] !== null && p[1] !== null)
        .sort((a, b) => a[0] - b[0]);
      return [pairs.map((p) => p[0]), pairs.map((p) => p[1])];
    });
    this.data = tables.length === 1 ? tables[0] : tables.length ? uPlot.join(tables) : [[]];
    const drawn = tables.reduce((n, t) => n + (t[0] as number[]).length, 0);
    this.el.dataset.points = String(drawn);
    this.draw();
  }

  // The axes fitted to the data and the view, not snapped to whole decades (axes.ts).
  private xRange(): [number, number] {
    const data = this.data;
    const e = positiveExtent(data[0] as number[], this.view.xInclude ?? [], this.view.pilot ?? [], [this.view.now ?? null]);
    if (!e) return [1, 10];
    return this.spec.logX ? logRange(e[0], e[1]) : [0, e[1] * 1.05];
  }

  private yRange(): [number, number] {
    const e = positiveExtent(...(this.data.slice(1) as (number | null)[][]));
    if (!e) return [1e-3, 1];
    return this.spec.logY ? logRange(e[0], e[1], 0.08) : [0, e[1] * 1.05];
  }

  // The pilot's band and the "now" line, under the curves.
  private drawView(u: uPlot): void {
    const { pilot, now } = this.view;
    const ctx = u.ctx;
    const { left, top, width, height } = u.bbox;
    const px = (v: number) => Math.min(left + width, Math.max(left, u.valToPos(v, "x", true)));
    ctx.save();
    if (pilot && pilot[1] > 0) {
      const a = px(Math.max(pilot[0], u.scales.x.min ?? pilot[0]));
      const b = px(pilot[1]);
      ctx.fillStyle = "rgba(240, 162, 2, 0.13)";
      ctx.fillRect(a, top, b - a, height);
      ctx.fillStyle = "#9a6a00";
      ctx.font = `${Math.round(11 * devicePixelRatio)}px system-ui, sans-serif`;
      ctx.fillText("pilot", a + 4 * devicePixelRatio, top + 14 * devicePixelRatio);
    }
    if (now && now > 0) {
      const x = px(now);
      ctx.strokeStyle = "#5c7080";
      ctx.setLineDash([4 * devicePixelRatio, 4 * devicePixelRatio]);
      ctx.lineWidth = devicePixelRatio;
      ctx.beginPath();
      ctx.moveTo(x, top);
      ctx.lineTo(x, top + height);
      ctx.stroke();
    }
    ctx.restore();
  }

  private options(width: number): uPlot.Options {
    const s = this.spec;
    const xText = (v: number) => (s.xLabel === "seconds" ? fmt.seconds(v) : fmt.count(v));
    const column = (u: uPlot, i: number) => u.data[i] as (number | null)[];
    return {
      title: s.title,
      width,
      height: s.height ?? 240,
      scales: {
        x: { time: false, distr: s.logX ? 3 : 1, range: () => this.xRange() },
        y: { distr: s.logY ? 3 : 1, range: () => this.yRange() },
      },
      hooks: { drawClear: [(u) => this.drawView(u)] },
      axes: [
        {
          label: s.xLabel,
          // Our own ticks on log axes, every one labelled (uPlot's filter keeps powers of ten).
          ...(s.logX ? { splits: (_u: uPlot, _i: number, min: number, max: number) => logSplits(min, max, 7), filter: (_u: uPlot, splits: number[]) => splits } : {}),
          stroke: "#52606d",
          grid: { stroke: "#e4e7eb" },
          values: (_u, splits) => splits.map((v) => (v == null ? "" : s.xLabel === "seconds" ? fmt.seconds(v) : fmt.count(v))),
        },
        {
          label: s.yLabel,
          ...(s.logY ? { splits: (_u: uPlot, _i: number, min: number, max: number) => logSplits(min, max), filter: (_u: uPlot, splits: number[]) => splits } : {}),
          stroke: "#52606d",
          grid: { stroke: "#e4e7eb" },
          size: 64,
          values: (_u, splits) => splits.map((v) => (v == null ? "" : String(Number(v.toPrecision(3))))),
        },
      ],
      legend: { show: true },
      series: [
        { label: s.xLabel, value: (u, _v, i, idx) => legendValue(column(u, i), idx, xText) },
        ...s.series.map((x) => ({
          value: (u: uPlot, _v: number, i: number, idx: number | null) => legendValue(column(u, i), idx, (v) => fmt.error(v)),
          label: x.label,
          stroke: x.color,
          width: 2,
          dash: x.dash,
          spanGaps: true,
          points: { show: true, size: 6, fill: x.color },
        })),
      ],
    };
  }

  private draw(): void {
    const width = Math.max(240, this.el.clientWidth || 480);
    const cols = this.data.length - 1;
    if (!this.plot || this.plot.series.length - 1 !== cols || cols !== this.spec.series.length) {
      this.plot?.destroy();
      this.plot = null;
      if (cols !== this.spec.series.length) return; // waiting for a matching setSeries
      this.plot = new uPlot(this.options(width), this.data, this.el);
    } else {
      // Resetting the scales calls the range functions again: the view may have moved.
      this.plot.setData(this.data, true);
      // uPlot refreshes legends only as the cursor moves: the latest values when nothing is
      // hovered (legendValue), not those of the first, empty, data.
      if (this.plot.cursor.idx === null || this.plot.cursor.idx === undefined) this.plot.setLegend({ idx: null as unknown as number });
    }
    // For the end-to-end test: where the axes end and what is shaded as the pilot.
    this.el.dataset.xMax = String(Number(this.xRange()[1].toPrecision(4)));
    this.el.dataset.yMax = String(Number(this.yRange()[1].toPrecision(4)));
    this.el.dataset.pilot = this.view.pilot ? this.view.pilot.map((v) => Number(v.toPrecision(6))).join(",") : "";
  }

  private resize(): void {
    if (!this.plot) return;
    const width = Math.max(240, this.el.clientWidth);
    if (Math.abs(width - this.plot.width) > 2) this.plot.setSize({ width, height: this.spec.height ?? 240 });
  }

  destroy(): void {
    this.observer.disconnect();
    this.plot?.destroy();
    this.plot = null;
  }
}
