// One render: the converging image with its buckets drawn over it, the sample-count and
// error heat maps, error charts that grow by one point per round, and the round table.
import { api, type Buckets, type PixelMap, type RenderDetail, type RoundRow } from "../api";
import { ErrorChart, PALETTE } from "../chart";
import { colorize, cssColor, decodeBase64, ERROR_MAP, SPP_MAP } from "../colormap";
import { append, clear, h } from "../dom";
import * as fmt from "../format";
import { throttle, type LiveEvent } from "../live";
import { progressText } from "./renders";
import { progressBar, setBadge, setProgress, setText, stateBadge, type Page } from "./page";

const ROUND_ROWS = 200;

class HeatMap {
  readonly canvas = h("canvas", { class: "heatmap" });
  readonly legend = h("div", { class: "legend" });
  readonly el: HTMLElement;
  samples = -1;

  constructor(
    readonly kind: "spp" | "error",
    title: string,
  ) {
    this.canvas.dataset.kind = kind;
    this.el = h("figure", { class: "card map", id: `map-${kind}` }, h("figcaption", {}, title), this.canvas, this.legend);
  }

  draw(map: PixelMap, samples: number): void {
    const table = this.kind === "spp" ? SPP_MAP : ERROR_MAP;
    const bytes = decodeBase64(map.data);
    this.canvas.width = map.width;
    this.canvas.height = map.height;
    this.canvas.style.aspectRatio = `${map.image_width} / ${map.image_height}`;
    const ctx = this.canvas.getContext("2d")!;
    ctx.putImageData(new ImageData(colorize(bytes, table), map.width, map.height), 0, 0);
    this.samples = samples;
    this.canvas.dataset.samples = String(samples);
    const stops = [0, 0.25, 0.5, 0.75, 1].map((t) => `${cssColor(table, t)} ${t * 100}%`).join(", ");
    const value = (v: number) => (this.kind === "spp" ? fmt.count(v) : fmt.error(v));
    clear(this.legend);
    this.legend.append(
      h("span", {}, value(map.lo)),
      h("span", { class: "ramp", style: `background: linear-gradient(to right, ${stops})` }),
      h("span", {}, (this.kind === "error" && map.hi < map.max ? "≥ " : "") + value(map.hi)),
      h("span", { class: "muted" }, ` mean ${value(map.mean)}`),
    );
  }
}

// A render's error against samples or time: the estimate and, when attached, the reference.
function errorChart(title: string, xLabel: string): ErrorChart {
  return new ErrorChart({
    title,
    xLabel,
    yLabel: "mean abs. error",
    logX: true,
    logY: true,
    series: [
      { label: "estimate", color: PALETTE[0] },
      { label: "vs reference", color: PALETTE[1] },
    ],
  });
}

export class RenderPage implements Page {
  el = h("section", { class: "page render-page" });
  private render: RenderDetail | null = null;
  private rounds: RoundRow[] = [];
  private exposure = 0;
  private buckets: Buckets | null = null;

  private header = h("div", { class: "render-header" });
  private preview = h("img", { class: "preview", id: "preview", alt: "preview" });
  private overlay = h("canvas", { class: "overlay", id: "bucket-overlay" });
  private showBuckets = h("input", { type: "checkbox", id: "show-buckets", checked: true });
  private exposureInput = h("input", { type: "range", id: "exposure", min: -6, max: 6, step: 0.1, value: 0 });
  private exposureLabel = h("span", { class: "muted" }, "+0.0 EV");
  private sppMap = new HeatMap("spp", "samples per pixel");
  private errorMap = new HeatMap("error", "error estimate (std. error of the mean)");
  private bySamples = errorChart("error vs samples", "samples");
  private byTime = errorChart("error vs wall time", "seconds");
  private roundBody = h("tbody");
  private roundNote = h("p", { class: "muted" });
  private resizer: ResizeObserver;
  private refreshImages = throttle(() => void this.loadImages(), 1000);
  private gone = false;

  constructor(private readonly id: string) {
    this.bySamples.el.id = "chart-samples";
    this.byTime.el.id = "chart-time";
    this.exposureInput.addEventListener("input", () => {
      this.exposure = Number(this.exposureInput.value);
      this.exposureLabel.textContent = `${this.exposure >= 0 ? "+" : ""}${this.exposure.toFixed(1)} EV`;
      this.loadPreview();
    });
    this.showBuckets.addEventListener("change", () => this.drawBuckets());
    this.preview.addEventListener("load", () => {
      this.preview.dataset.samples = this.preview.dataset.pending ?? "";
      this.drawBuckets();
    });
    this.resizer = new ResizeObserver(() => this.drawBuckets());
    this.resizer.observe(this.preview);

    this.el.append(
      h("p", { class: "crumbs" }, h("a", { href: "#/renders" }, "Renders"), " / ", id),
      this.header,
      h(
        "div",
        { class: "image-row" },
        h(
          "figure",
          { class: "card image-card" },
          h("figcaption", {}, "image"),
          h("div", { class: "image-stack" }, this.preview, this.overlay),
          h(
            "div",
            { class: "controls" },
            h("label", {}, "exposure ", this.exposureInput, " ", this.exposureLabel),
            h("label", {}, this.showBuckets, " bucket boundaries"),
          ),
        ),
        this.sppMap.el,
        this.errorMap.el,
      ),
      h("div", { class: "chart-row" }, h("div", { class: "card" }, this.bySamples.el), h("div", { class: "card" }, this.byTime.el)),
      h("h2", {}, "Rounds"),
      this.roundNote,
      h(
        "div",
        { class: "table-wrap" },
        h(
          "table",
          { class: "rounds", id: "rounds-table" },
          h("thead", {}, h("tr", {}, ...["round", "samples in round", "samples", "seconds", "error estimate", "error vs reference"].map((t) => h("th", {}, t)))),
          this.roundBody,
        ),
      ),
    );
    void this.load();
  }

  private async load(): Promise<void> {
    try {
      this.render = await api.render(this.id);
    } catch (e) {
      clear(this.header);
      this.header.append(h("p", { class: "error" }, (e as Error).message));
      return;
    }
    this.showHeader();
    try {
      const { rounds } = await api.rounds(this.id);
      this.rounds = rounds;
    } catch {
      this.rounds = [];
    }
    this.showRounds();
    this.refreshImages(); // through the throttle, like every later refresh
  }

  private loadPreview(): void {
    if (!this.render) return;
    const samples = this.render.samples_done;
    this.preview.dataset.pending = String(samples);
    this.preview.src = api.previewUrl(this.id, this.exposure, samples);
  }

  // The render's details (outcome, rays), its images and buckets: at most once a second.
  private async loadImages(): Promise<void> {
    if (!this.render || this.gone) return;
    const samples = this.render.samples_done;
    this.loadPreview();
    const [detail, spp, err, buckets] = await Promise.allSettled([
      api.render(this.id),
      api.map(this.id, "spp"),
      api.map(this.id, "error"),
      api.buckets(this.id),
    ]);
    if (this.gone) return;
    if (detail.status === "fulfilled" && detail.value.samples_done >= (this.render?.samples_done ?? 0)) {
      this.render = detail.value;
      this.showHeader();
    }
    if (spp.status === "fulfilled") this.sppMap.draw(spp.value, samples);
    if (err.status === "fulfilled") this.errorMap.draw(err.value, samples);
    if (buckets.status === "fulfilled") {
      this.buckets = buckets.value;
      this.drawBuckets();
    }
  }

  private drawBuckets(): void {
    const img = this.preview;
    const w = img.clientWidth;
    const hgt = img.clientHeight;
    const dpr = window.devicePixelRatio || 1;
    this.overlay.width = Math.max(1, Math.round(w * dpr));
    this.overlay.height = Math.max(1, Math.round(hgt * dpr));
    this.overlay.style.width = `${w}px`;
    this.overlay.style.height = `${hgt}px`;
    const ctx = this.overlay.getContext("2d")!;
    ctx.clearRect(0, 0, this.overlay.width, this.overlay.height);
    const b = this.buckets;
    this.overlay.dataset.buckets = String(b?.buckets.length ?? 0);
    if (!b || !this.showBuckets.checked || !b.buckets.length || !w) return;
    const sx = this.overlay.width / b.width;
    const sy = this.overlay.height / b.height;
    ctx.lineWidth = Math.max(1, dpr);
    for (const [x, y, bw, bh, , converged] of b.buckets) {
      ctx.strokeStyle = converged ? "rgba(80, 220, 120, 0.85)" : "rgba(255, 170, 40, 0.9)";
      ctx.strokeRect(x * sx + 0.5, y * sy + 0.5, bw * sx - 1, bh * sy - 1);
    }
  }

  // Built once, then updated in place several times a second (see page.ts).
  private buildHeader(r: RenderDetail): void {
    clear(this.header);
    const cancel = h("button", { type: "button", id: "cancel-render" }, "cancel");
    cancel.addEventListener("click", async () => {
      cancel.disabled = true;
      try {
        this.render = await api.cancel(r.id);
        this.showHeader();
      } catch {
        cancel.disabled = false;
      }
    });
    const stat = (key: string, label: string) => h("div", {}, h("dt", {}, label), h("dd", { "data-stat": key }));
    append(this.header, [
      h("h1", {}, `${r.id} `, h("span", { class: "muted" }, `${r.scene} · ${r.method} · ${r.width}×${r.height} · seed ${r.seed}`), " ", stateBadge(r.state), " ", cancel),
      h("div", { class: "render-progress", id: "render-progress" }, progressBar(r.progress, progressText(r))),
      h(
        "dl",
        { class: "stats" },
        stat("samples", "samples"),
        stat("rate", "samples/s"),
        stat("rounds", "rounds"),
        stat("error", "error estimate"),
        stat("reference", "error vs reference"),
        stat("time", "time"),
        stat("rays", "rays"),
      ),
      h("p", { class: "muted params" }),
      h("p", { class: "error" }),
      h("p", { class: "muted outcome" }),
    ]);
  }

  private showHeader(): void {
    const r = this.render;
    if (!r) return;
    if (!this.header.querySelector("#render-progress")) this.buildHeader(r);
    const q = <T extends HTMLElement>(sel: string) => this.header.querySelector<T>(sel)!;
    this.header.dataset.state = r.state;
    this.header.dataset.progress = r.progress.toFixed(4);
    setBadge(q("h1 .badge"), r.state);
    q<HTMLButtonElement>("#cancel-render").hidden = r.state !== "running" && r.state !== "queued";
    setProgress(q("#render-progress .progress"), r.progress, progressText(r));
    const stats: [string, string][] = [
      ["samples", fmt.count(r.samples_done)],
      ["rate", fmt.count(r.samples_per_second)],
      ["rounds", String(r.rounds)],
      ["error", fmt.error(r.error_estimate)],
      ["reference", fmt.error(r.error_vs_reference)],
      ["time", fmt.seconds(r.seconds)],
      ["rays", fmt.count(r.rays ?? 0)],
    ];
    for (const [key, value] of stats) setText(q(`dd[data-stat="${key}"]`), value);
    const params = Object.entries(r.strategy ?? {})
      .filter(([k, v]) => k !== "method" && v !== 0 && v !== "")
      .map(([k, v]) => `${k} ${v}`)
      .join(" · ");
    const outcome = Object.keys(r.outcome ?? {}).length ? `outcome: ${JSON.stringify(r.outcome)}` : "";
    setText(q("p.params"), params);
    setText(q("p.error"), r.error ?? "");
    setText(q("p.outcome"), outcome);
  }

  private showRounds(): void {
    const x = this.rounds.map((r) => r.samples_total);
    const t = this.rounds.map((r) => r.seconds);
    const est = this.rounds.map((r) => r.error_estimate);
    const ref = this.rounds.map((r) => r.error_vs_reference);
    this.bySamples.setSeries([
      { x, y: est },
      { x, y: ref },
    ]);
    this.byTime.setSeries([
      { x: t, y: est },
      { x: t, y: ref },
    ]);
    clear(this.roundBody);
    // Newest first: the table grows at the top while a render runs. Dammertz renders may
    // have thousands of rounds; the charts show them all, the table the newest.
    const shown = this.rounds.slice(-ROUND_ROWS).reverse();
    this.roundNote.textContent =
      this.rounds.length > shown.length ? `newest ${shown.length} of ${this.rounds.length} rounds` : "";
    for (const r of shown) {
      this.roundBody.append(
        h(
          "tr",
          {},
          h("td", { class: "num" }, r.index),
          h("td", { class: "num" }, fmt.count(r.samples_in_round)),
          h("td", { class: "num" }, fmt.count(r.samples_total)),
          h("td", { class: "num" }, fmt.seconds(r.seconds)),
          h("td", { class: "num" }, fmt.error(r.error_estimate)),
          h("td", { class: "num" }, fmt.error(r.error_vs_reference)),
        ),
      );
    }
    this.el.dataset.rounds = String(this.rounds.length);
  }

  onEvent(e: LiveEvent): void {
    if (e.type === "render") {
      const mine = e.renders.find((r) => r.id === this.id);
      if (mine && this.render) {
        const changed = mine.state !== this.render.state || mine.samples_done !== this.render.samples_done;
        this.render = { ...this.render, ...mine };
        this.showHeader();
        if (changed) this.refreshImages(); // at most once a second
      }
    } else if (e.type === "round") {
      const mine = e.rounds.filter((r) => r.id === this.id);
      if (!mine.length) return;
      for (const r of mine) {
        if (r.position === this.rounds.length) this.rounds.push(r);
        else if (r.position > this.rounds.length) {
          void this.resync();
          return;
        }
      }
      this.showRounds();
      this.refreshImages();
    } else if (e.type === "resync") {
      void this.resync();
    }
  }

  private async resync(): Promise<void> {
    await this.load();
  }

  dispose(): void {
    this.gone = true;
    this.refreshImages.cancel();
    this.resizer.disconnect();
    this.bySamples.destroy();
    this.byTime.destroy();
  }
}
