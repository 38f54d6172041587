// Error curves drawn with uPlot: one chart per view, resized with its container, data
// replaced as rounds arrive. The number of points drawn is kept in data-points so the
// end-to-end test can check that every round added one.
import uPlot from "uplot";
import "uplot/dist/uPlot.min.css";
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

export class ErrorChart {
  readonly el: HTMLDivElement;
  private plot: uPlot | null = null;
  private observer: ResizeObserver;
  private spec: ChartSpec;
  private data: uPlot.AlignedData = [[]];

  constructor(spec: ChartSpec) {
    this.spec = spec;
    this.el = document.createElement("div");
    this.el.className = "chart";
    this.el.dataset.points = "0";
    this.observer = new ResizeObserver(() => this.resize());
    this.observer.observe(this.el);
  }

  /** Series of (x, y) pairs per series; non-positive values are left out (log scales). */
  setSeries(series: { x: number[]; y: (number | null)[] }[], spec?: Partial<ChartSpec>): void {
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

  private options(width: number): uPlot.Options {
    const s = this.spec;
    return {
      title: s.title,
      width,
      height: s.height ?? 240,
      scales: { x: { time: false, distr: s.logX ? 3 : 1 }, y: { distr: s.logY ? 3 : 1 } },
      axes: [
        {
          label: s.xLabel,
          stroke: "#52606d",
          grid: { stroke: "#e4e7eb" },
          values: (_u, splits) => splits.map((v) => (v == null ? "" : s.xLabel === "seconds" ? fmt.seconds(v) : fmt.count(v))),
        },
        {
          label: s.yLabel,
          stroke: "#52606d",
          grid: { stroke: "#e4e7eb" },
          size: 64,
          values: (_u, splits) => splits.map((v) => (v == null ? "" : String(Number(v.toPrecision(3))))),
        },
      ],
      legend: { show: true },
      series: [
        { label: s.xLabel },
        ...s.series.map((x) => ({
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
      this.plot.setData(this.data);
    }
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
