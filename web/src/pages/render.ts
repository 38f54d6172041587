// One render: the converging image with its buckets drawn over it, the sample-count and
// error heat maps, error charts that grow by one point per round, the round table and the
// render's log; what an operator does to it (priority, download, resubmit, delete).
import { api, ApiError, type Buckets, type MethodInfo, type PixelMap, type RenderDetail, type RoundRow } from "../api";
import { pilotRounds, pilotSamples } from "../axes";
import { ErrorChart, PALETTE, type ChartView } from "../chart";
import { colorize, cssColor, decodeBase64, ERROR_MAP, SPP_MAP } from "../colormap";
import { biasBeyondNoise, biasText } from "../bias";
import { append, clear, h } from "../dom";
import { etaSeconds, etaText } from "../eta";
import { eventLines } from "../events";
import * as fmt from "../format";
import { throttle, type LiveEvent } from "../live";
import { findMethod, paramSummary } from "../params";
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
const ESTIMATE = { label: "estimate", color: PALETTE[0] };
const REFERENCE = { label: "vs reference", color: PALETTE[1] };

function errorChart(title: string, xLabel: string): ErrorChart {
  return new ErrorChart({
    title,
    xLabel,
    yLabel: "mean abs. error",
    logX: true,
    logY: true,
    series: [ESTIMATE],
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
  private roundNote = h("p", { class: "muted", id: "round-note" });
  private chartNote = h("p", { class: "muted chart-note", id: "chart-note" });
  private hasReference = false;
  private eventList = h("ol", { class: "events", id: "render-events" });
  private eventNote = h("p", { class: "muted", id: "render-events-note" });
  private refreshEvents = throttle(() => void this.loadEvents(), 2000);
  private resizer: ResizeObserver;
  private refreshImages = throttle(() => void this.loadImages(), 1000);
  private gone = false;
  // Which parameters each method reads: the render's own are all its page shows.
  private methods: MethodInfo[] = [];

  constructor(private readonly id: string) {
    api
      .methods()
      .then(({ methods }) => {
        this.methods = methods;
        this.showHeader();
      })
      .catch(() => {}); // without the list the parameters line stays empty
    this.bySamples.el.id = "chart-samples";
    this.byTime.el.id = "chart-time";
    this.exposureInput.addEventListener("input", () => {
      this.exposure = Number(this.exposureInput.value);
      this.exposureLabel.textContent = `${this.exposure >= 0 ? "+" : ""}${this.exposure.toFixed(1)} EV`;
      this.loadPreview();
    });
    this.showBuckets.addEventListener("change", () => this.drawBuckets());
    // No image yet (a queued render, or nothing merged): an empty frame, not a broken icon.
    this.preview.addEventListener("error", () => (this.preview.style.visibility = "hidden"));
    this.preview.addEventListener("load", () => {
      this.preview.style.visibility = "";
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
      this.chartNote,
      h("div", { class: "chart-row" }, h("div", { class: "card" }, this.bySamples.el), h("div", { class: "card" }, this.byTime.el)),
      h("h2", {}, "Events"),
      this.eventNote,
      h("div", { class: "card events-card" }, this.eventList),
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
    this.refreshEvents();
  }

  // The render's log, newest last. A coordinator without GET .../events (404) says so
  // once rather than showing an error.
  private async loadEvents(): Promise<void> {
    if (this.gone) return;
    let body: unknown;
    try {
      body = await api.events(this.id);
    } catch (e) {
      if (this.gone) return;
      const missing = e instanceof ApiError && e.status === 404;
      this.eventNote.textContent = missing ? "This coordinator keeps no event log for renders." : `cannot load events: ${(e as Error).message}`;
      this.eventList.dataset.count = "0";
      this.eventList.parentElement!.hidden = true;
      return;
    }
    if (this.gone) return;
    const lines = eventLines(body);
    clear(this.eventList);
    for (const l of lines)
      this.eventList.append(
        h(
          "li",
          { "data-kind": l.kind },
          h("time", { class: "muted live-value" }, l.timeMs === null ? "" : new Date(l.timeMs).toLocaleTimeString()),
          " ",
          h("span", { class: "event-kind" }, l.kind.replace(/_/g, " ")),
          " ",
          h("span", { class: "muted" }, l.detail),
        ),
      );
    this.eventList.dataset.count = String(lines.length);
    this.eventList.parentElement!.hidden = false;
    // A long render keeps its first and last events; the coordinator says how many it dropped.
    const omitted = body && typeof body === "object" && "omitted" in body ? Number((body as { omitted: unknown }).omitted) : 0;
    this.eventNote.textContent = !lines.length ? "No events yet." : omitted > 0 ? `${omitted} events between the first and the last are not kept.` : "";
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
      h(
        "h1",
        {},
        h("span", { class: "render-name", id: "render-name" }),
        " ",
        h("span", { class: "muted" }, `${r.scene} · ${r.method} · ${r.width}×${r.height} · seed ${r.seed}`),
        " ",
        stateBadge(r.state),
        " ",
        cancel,
      ),
      this.actions(r),
      h("div", { class: "render-progress", id: "render-progress" }, progressBar(r.progress, progressText(r))),
      h(
        "dl",
        { class: "stats" },
        stat("submitted", "submitted"),
        stat("eta", "ETA"),
        stat("samples", "samples"),
        stat("rate", "samples/s"),
        stat("rounds", "rounds"),
        stat("error", "error estimate"),
        stat("reference", "error vs reference"),
        stat("bias", "mean bias vs reference"),
        stat("time", "time"),
        stat("rays", "rays"),
      ),
      h("p", { class: "muted params" }),
      h("p", { class: "error" }),
      h("p", { class: "muted outcome", id: "render-outcome" }),
      h("p", { class: "action-message", id: "render-action-message", role: "status" }),
    ]);
  }

  // Priority, downloads, resubmit and delete: what Deadline Monitor offers on a job.
  private actions(r: RenderDetail): HTMLElement {
    const say = (text: string, isError: boolean) => {
      const m = this.header.querySelector<HTMLElement>("#render-action-message")!;
      m.textContent = text;
      m.classList.toggle("error", isError);
    };
    const priority = h("input", { type: "number", id: "priority-input", step: 1, value: r.priority ?? 0, "aria-label": "priority" });
    const setPriority = h("button", { type: "button", id: "priority-set", class: "small" }, "set priority");
    setPriority.addEventListener("click", async () => {
      setPriority.disabled = true;
      try {
        this.render = await api.setPriority(this.id, Math.trunc(Number(priority.value)));
        say(`priority ${this.render.priority ?? priority.value}`, false);
        this.showHeader();
      } catch (e) {
        say((e as Error).message, true);
      } finally {
        setPriority.disabled = false;
      }
    });
    const remove = h("button", { type: "button", id: "delete-render", class: "small danger" }, "delete");
    remove.addEventListener("click", async () => {
      if (!window.confirm(`Delete ${this.id} and its images? This cannot be undone.`)) return;
      remove.disabled = true;
      try {
        await api.remove(this.id);
        location.hash = "#/renders";
      } catch (e) {
        say((e as Error).message, true);
        remove.disabled = false;
      }
    });
    const exr = h("a", { class: "button small", id: "download-exr", href: api.exrUrl(this.id), download: `${this.id}.exr` }, "EXR");
    const png = h("a", { class: "button small", id: "download-png", href: api.pngUrl(this.id, r.width, r.height), download: `${this.id}.png` }, "PNG");
    const resubmit = h("a", { class: "button small", id: "resubmit", href: `#/renders?from=${encodeURIComponent(this.id)}` }, "resubmit with changes");
    return h(
      "div",
      { class: "render-actions" },
      h("span", { class: "priority", id: "priority-controls" }, h("label", { class: "pick" }, "priority", priority), setPriority),
      h("span", { class: "muted" }, "download"),
      exr,
      png,
      resubmit,
      remove,
    );
  }

  private showHeader(): void {
    const r = this.render;
    if (!r) return;
    if (!this.header.querySelector("#render-progress")) this.buildHeader(r);
    const q = <T extends HTMLElement>(sel: string) => this.header.querySelector<T>(sel)!;
    this.header.dataset.state = r.state;
    this.header.dataset.progress = r.progress.toFixed(4);
    setBadge(q("h1 .badge"), r.state);
    const active = r.state === "running" || r.state === "queued";
    q<HTMLButtonElement>("#cancel-render").hidden = !active;
    // The server refuses both otherwise (409): a finished render has no priority to
    // change, and an unfinished one must be cancelled before it is deleted.
    q("#priority-controls").hidden = !active;
    q("#delete-render").hidden = active;
    const priority = q<HTMLInputElement>("#priority-input");
    if (document.activeElement !== priority) priority.value = String(r.priority ?? 0);
    setText(q("#render-name"), r.name ? `${r.name} (${r.id})` : r.id);
    setProgress(q("#render-progress .progress"), r.progress, progressText(r));
    const stats: [string, string][] = [
      ["submitted", r.created_ms ? new Date(r.created_ms).toLocaleString() : "–"],
      ["eta", etaText(r, fmt.seconds)],
      ["samples", fmt.count(r.samples_done)],
      ["rate", fmt.count(r.samples_per_second)],
      ["rounds", String(r.rounds)],
      ["error", fmt.error(r.error_estimate)],
      ["reference", fmt.error(r.error_vs_reference)],
      ["time", fmt.seconds(r.seconds)],
      ["rays", fmt.count(r.rays ?? 0)],
    ];
    for (const [key, value] of stats) setText(q(`dd[data-stat="${key}"]`), value);
    this.showBias(q(`dd[data-stat="bias"]`), r);
    setText(q("p.params"), paramSummary(findMethod(this.methods, r.method), r.strategy));
    setText(q("p.error"), r.error ?? "");
    setText(q("p.outcome"), outcomeText(r.outcome));
  }

  // Beside E, the last round's mean bias ± its SE, marked when beyond 3 SE: E falls as a
  // biased method converges while its image stays too dark. Shown only with a bias (a
  // reference, not black), so a render without one keeps its header as it was.
  private showBias(dd: HTMLElement, r: RenderDetail): void {
    const known = r.mean_bias !== null && r.mean_bias !== undefined;
    dd.parentElement!.hidden = !known;
    setText(dd, biasText(r.mean_bias, r.mean_bias_se));
    const beyond = biasBeyondNoise(r.mean_bias, r.mean_bias_se);
    dd.classList.toggle("biased", beyond);
    dd.title = beyond ? "beyond 3 standard errors: a bias the image's noise does not explain" : "";
  }

  private showRounds(): void {
    this.drawCharts();
    this.showRoundTable();
  }

  private drawCharts(): void {
    const x = this.rounds.map((r) => r.samples_total);
    const t = this.rounds.map((r) => r.seconds);
    const est = this.rounds.map((r) => r.error_estimate);
    const ref = this.rounds.map((r) => r.error_vs_reference);
    // The reference's curve only when there is one: an empty series is a legend of blanks.
    const hasReference = ref.some((v) => v !== null && v > 0);
    const spec = hasReference !== this.hasReference ? { series: hasReference ? [ESTIMATE, REFERENCE] : [ESTIMATE] } : undefined;
    this.hasReference = hasReference;
    const views = this.chartViews(x, t);
    this.bySamples.setSeries(hasReference ? [{ x, y: est }, { x, y: ref }] : [{ x, y: est }], spec, views.samples);
    this.byTime.setSeries(hasReference ? [{ x: t, y: est }, { x: t, y: ref }] : [{ x: t, y: est }], spec, views.time);
  }

  private showRoundTable(): void {
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

  // What the charts show besides the rounds: axes that reach the render's plan and its
  // expected end, the pilot (optimal methods) shaded, and where the render is now, so a
  // long pilot round is not an empty chart.
  private chartViews(x: number[], t: number[]): { samples: ChartView; time: ChartView } {
    const r = this.render;
    if (!r) return { samples: {}, time: {} };
    const running = r.state === "running";
    const pilot = pilotSamples(r);
    const inPilot = pilotRounds(x, pilot);
    const pilotOpen = pilot !== null && r.samples_done < pilot && running;
    const left = running ? etaSeconds(r) : null;
    // Dammertz's plan is a cap it rarely reaches: its axis follows what it traced.
    const planned = r.method === "dammertz" ? r.samples_done : Math.max(r.samples_planned, r.samples_done);
    // Before the first round ends, the axis starts two decades below the plan, so that the
    // pilot's band and the "now" line have room.
    const firstX = x.find((v) => v > 0) ?? Math.max(1, Math.min(planned / 100, r.samples_done > 0 ? r.samples_done / 10 : Infinity));
    const firstT = t.find((v) => v > 0) ?? Math.max(0.1, r.seconds / 10);
    const pilotEndT = pilotOpen ? r.seconds : inPilot ? t[inPilot - 1] : null;
    this.chartNote.textContent = pilotOpen
      ? `pilot: ${fmt.count(r.samples_done)} of its ${fmt.count(pilot)} samples traced (${fmt.percent(r.samples_done / pilot)}); its error comes when its round ends`
      : x.length === 0 && running
        ? "waiting for the first round to end"
        : r.state === "queued"
          ? `queued${r.queue_position ? ` (#${r.queue_position})` : ""}: waiting for a worker`
          : "";
    this.chartNote.dataset.pilot = pilotOpen ? "running" : inPilot ? "done" : "none";
    return {
      samples: {
        xInclude: [firstX, planned, r.samples_done],
        pilot: pilot ? [firstX, pilot] : null,
        now: running ? r.samples_done : null,
      },
      time: {
        xInclude: [firstT, r.seconds + (left ?? 0)],
        pilot: pilotEndT ? [firstT, pilotEndT] : null,
        now: running ? r.seconds : null,
      },
    };
  }

  onEvent(e: LiveEvent): void {
    if (e.type === "render") {
      const mine = e.renders.find((r) => r.id === this.id);
      if (mine && this.render) {
        const changed = mine.state !== this.render.state || mine.samples_done !== this.render.samples_done;
        const stateChanged = mine.state !== this.render.state;
        this.render = { ...this.render, ...mine };
        this.showHeader();
        if (changed) this.refreshImages(); // at most once a second
        if (changed) this.drawCharts(); // the "now" line and the pilot's progress
        if (stateChanged) this.refreshEvents();
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
      this.refreshEvents();
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
    this.refreshEvents.cancel();
    this.resizer.disconnect();
    this.bySamples.destroy();
    this.byTime.destroy();
  }
}

// A render's outcome as words: "budget 590k · rounds 10 · unspent 0", not its JSON.
export function outcomeText(outcome: Record<string, unknown> | undefined): string {
  const parts = Object.entries(outcome ?? {}).map(([k, v]) => {
    const value = typeof v === "number" ? (Number.isInteger(v) ? fmt.count(v) : fmt.error(v)) : typeof v === "string" || typeof v === "boolean" ? String(v) : "…";
    return `${k.replace(/_/g, " ")} ${value}`;
  });
  return parts.length ? `outcome: ${parts.join(" · ")}` : "";
}
