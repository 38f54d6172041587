// Renders: every render with its thumbnail, progress, ETA and error, sorted and filtered
// as the address says; a form to submit one (or resubmit one with changes); cancel buttons.
import { api, ApiError, type MethodInfo, type RenderDetail, type RenderSummary, type SceneList } from "../api";
import { biasText } from "../bias";
import { clear, h } from "../dom";
import { etaText } from "../eta";
import * as fmt from "../format";
import { matches, sortRenders, viewFromQuery, type RenderFilter, type SortKey } from "../listing";
import type { LiveEvent } from "../live";
import { fieldSpecs, findMethod, strategyFromFields } from "../params";
import { progressBar, setBadge, setProgress, setText, stateBadge, type Page } from "./page";
import { ThumbnailSchedule } from "../thumbnails";

// The table's columns: heading, and the sort key a click on it picks.
const COLUMNS: [string, SortKey | null][] = [
  ["", null],
  ["render", "name"],
  ["submitted", "created"],
  ["scene", "scene"],
  ["method", "method"],
  ["state", "state"],
  ["progress", "progress"],
  ["ETA", "eta"],
  ["samples/s", null],
  ["error estimate", "error"],
  ["error vs reference", null],
  ["rounds", null],
  ["time", "time"],
  ["", null],
];

// A thumbnail is fetched again at most this often per render while it changes.
const THUMBNAIL_MS = 3000;

export function progressText(r: RenderSummary): string {
  if (r.buckets_total && r.state !== "done")
    return `${r.buckets_converged ?? 0}/${r.buckets_total} buckets converged · ${fmt.percent(r.progress)}`;
  // Dammertz's planned samples are only a cap: it stops where its buckets converge.
  if (r.method === "dammertz") return `${fmt.count(r.samples_done)} samples · ${fmt.percent(r.progress)}`;
  const planned = r.samples_planned ? ` / ${fmt.count(r.samples_planned)}` : "";
  return `${fmt.count(r.samples_done)}${planned} · ${fmt.percent(r.progress)}`;
}

// When a render was submitted: the time today, the date before.
function submitted(ms: number): string {
  if (!ms) return "–";
  const d = new Date(ms);
  const today = new Date().toDateString() === d.toDateString();
  return today ? d.toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit" }) : d.toLocaleDateString();
}

export class RendersPage implements Page {
  el = h("section", { class: "page renders-page" });
  private rows = new Map<string, HTMLTableRowElement>();
  private renders = new Map<string, RenderSummary>();
  private tbody = h("tbody");
  private empty = h("p", { class: "muted empty" }, "No renders yet: submit one above.");
  private message = h("p", { class: "form-message", role: "status" });
  private fields = h("div", { class: "method-fields" });
  private form!: HTMLFormElement;
  private scenes: SceneList | null = null;
  // Each method's parameters, as the coordinator declares them (GET /api/methods).
  private methods: MethodInfo[] = [];
  private filter: RenderFilter;
  private sort: SortKey;
  private descending: boolean;
  private filterBar: HTMLElement;
  private headRow = h("tr");
  private order = "";
  private thumbs = new Map<string, { schedule: ThumbnailSchedule; timer: ReturnType<typeof setTimeout> | null }>();
  private resubmitFrom: string | null;
  private formReady: Promise<void>;

  constructor(query = new URLSearchParams()) {
    ({ filter: this.filter, sort: this.sort, descending: this.descending } = viewFromQuery(query));
    this.resubmitFrom = query.get("from");
    this.filterBar = this.buildFilterBar();
    this.el.append(
      h("h1", {}, "Renders"),
      this.buildForm(),
      this.filterBar,
      h("div", { class: "table-wrap" }, h("table", { class: "renders", id: "renders-table" }, h("thead", {}, this.headRow), this.tbody)),
      this.empty,
    );
    this.showHeadings();
    void this.load();
    this.formReady = this.loadScenes();
    if (this.resubmitFrom) void this.prefill(this.resubmitFrom);
  }

  private buildFilterBar(): HTMLElement {
    const select = (id: string, label: string, options: [string, string][], value: string) =>
      h("label", { class: "pick" }, label, h("select", { id }, ...options.map(([v, t]) => h("option", { value: v, selected: v === value }, t))));
    const states: [string, string][] = [["", "any"], ["active", "queued or running"], ...["queued", "running", "done", "failed", "cancelled"].map((s): [string, string] => [s, s])];
    const bar = h(
      "div",
      { class: "filter-bar", id: "render-filter" },
      select("filter-state", "state", states, this.filter.state),
      select("filter-method", "method", [["", "any"]], this.filter.method),
      select("filter-scene", "scene", [["", "any"]], this.filter.scene),
      h("label", { class: "pick" }, "name or id", h("input", { id: "filter-text", type: "search", value: this.filter.text, placeholder: "filter" })),
    );
    bar.addEventListener("input", () => this.readFilter());
    bar.addEventListener("change", () => this.readFilter());
    return bar;
  }

  private readFilter(): void {
    const v = (id: string) => this.filterBar.querySelector<HTMLInputElement | HTMLSelectElement>(`#${id}`)!.value;
    this.filter = { state: v("filter-state"), method: v("filter-method"), scene: v("filter-scene"), text: v("filter-text") };
    this.applyView();
    this.saveView();
  }

  // The view goes into the address, so a reload or a shared link shows the same list.
  private saveView(): void {
    const q = new URLSearchParams();
    if (this.filter.state) q.set("state", this.filter.state);
    if (this.filter.method) q.set("method", this.filter.method);
    if (this.filter.scene) q.set("scene", this.filter.scene);
    if (this.filter.text) q.set("q", this.filter.text);
    if (this.sort !== "created") q.set("sort", this.sort);
    if (this.descending !== (this.sort === "created")) q.set("dir", this.descending ? "desc" : "asc");
    const s = q.toString();
    // replaceState: no hashchange, so the page (and its form) stays as it is.
    history.replaceState(null, "", `#/renders${s ? `?${s}` : ""}`);
  }

  private showHeadings(): void {
    clear(this.headRow);
    for (const [title, key] of COLUMNS) {
      if (!key) {
        this.headRow.append(h("th", {}, title));
        continue;
      }
      const arrow = key === this.sort ? (this.descending ? " ▾" : " ▴") : "";
      const th = h("th", { class: "sortable", "data-sort": key, "aria-sort": key === this.sort ? (this.descending ? "descending" : "ascending") : null }, title + arrow);
      th.addEventListener("click", () => {
        if (this.sort === key) this.descending = !this.descending;
        else {
          this.sort = key;
          this.descending = key === "created" || key === "progress" || key === "time";
        }
        this.showHeadings();
        this.applyView();
        this.saveView();
      });
      this.headRow.append(th);
    }
  }

  // Rows in the chosen order, the filtered-out ones hidden; rows are moved, never rebuilt.
  private applyView(): void {
    const all = [...this.renders.values()];
    const sorted = sortRenders(all, this.sort, this.descending);
    const order = sorted.map((r) => r.id).join(",");
    if (order !== this.order) {
      this.order = order;
      for (const r of sorted) this.tbody.append(this.rows.get(r.id)!);
    }
    let shown = 0;
    for (const r of all) {
      const visible = matches(r, this.filter);
      this.rows.get(r.id)!.hidden = !visible;
      if (visible) shown++;
    }
    this.empty.textContent = this.rows.size ? "No render matches the filter." : "No renders yet: submit one above.";
    this.empty.hidden = shown > 0;
    this.el.dataset.shown = String(shown);
  }

  private buildForm(): HTMLElement {
    const scene = h("select", { name: "scene", id: "submit-scene" });
    const method = h("select", { name: "method", id: "submit-method" });
    this.form = h(
      "form",
      { class: "card submit-form", id: "submit-form" },
      h("h2", {}, "Submit a render"),
      h(
        "div",
        { class: "form-row" },
        h("label", {}, "scene", scene),
        h("label", {}, "resolution", h("input", { name: "resolution", id: "submit-resolution", value: "128x128", pattern: "\\d+x\\d+", required: true, size: 9 })),
        h("label", {}, "seed", h("input", { name: "seed", id: "submit-seed", inputmode: "numeric", pattern: "[0-9]+", value: "0" })),
        h("label", {}, "method", method),
        h("label", {}, "name", h("input", { name: "name", id: "submit-name", maxlength: 200, placeholder: "optional", size: 16 })),
      ),
      this.fields,
      h("div", { class: "form-row" }, h("button", { type: "submit", id: "submit-button" }, "Submit"), this.message),
    );
    method.addEventListener("change", () => this.showFields());
    this.form.addEventListener("submit", (e) => {
      e.preventDefault();
      void this.submit();
    });
    return this.form;
  }

  private async loadScenes(): Promise<void> {
    try {
      [this.scenes, { methods: this.methods }] = await Promise.all([api.scenes(), api.methods()]);
    } catch (e) {
      this.setMessage(`cannot load scenes and methods: ${(e as Error).message}`, true);
      return;
    }
    const scene = this.form.querySelector<HTMLSelectElement>("#submit-scene")!;
    const method = this.form.querySelector<HTMLSelectElement>("#submit-method")!;
    for (const s of this.scenes.scenes) scene.append(h("option", { value: s }, s));
    for (const m of this.methods.filter((m) => m.submittable)) method.append(h("option", { value: m.name, title: m.summary }, m.name));
    this.showFields();
    const fill = (id: string, values: string[], value: string) => {
      const select = this.filterBar.querySelector<HTMLSelectElement>(`#${id}`)!;
      for (const v of values) select.append(h("option", { value: v, selected: v === value }, v));
    };
    fill("filter-method", this.scenes.methods, this.filter.method);
    fill("filter-scene", this.scenes.scenes, this.filter.scene);
  }

  // "Resubmit with changes" from a render's page: the form holds that render's spec.
  private async prefill(id: string): Promise<void> {
    let r: RenderDetail;
    try {
      [r] = await Promise.all([api.render(id), this.formReady]);
    } catch (e) {
      this.setMessage(`cannot load ${id} to resubmit: ${(e as Error).message}`, true);
      return;
    }
    const set = (sel: string, value: string) => {
      const el = this.form.querySelector<HTMLInputElement | HTMLSelectElement>(sel);
      if (el) el.value = value;
    };
    set("#submit-scene", r.scene);
    set("#submit-resolution", `${r.width}x${r.height}`);
    set("#submit-seed", r.seed);
    set("#submit-name", r.name ?? "");
    set("#submit-method", r.method);
    this.form.querySelector("#submit-method")!.dispatchEvent(new Event("change"));
    for (const [k, v] of Object.entries(r.strategy ?? {}))
      if (typeof v === "number" || typeof v === "string") set(`[data-param="${k}"]`, String(v));
    this.form.dataset.from = id;
    this.setMessage(`the form holds ${id}'s spec: change what you need and submit`, false);
    this.form.scrollIntoView();
  }

  // The chosen method's parameters only, each with its default, bounds and help.
  private showFields(): void {
    clear(this.fields);
    const method = findMethod(this.methods, this.form.querySelector<HTMLSelectElement>("#submit-method")!.value);
    if (!method) return;
    this.fields.dataset.method = method.name;
    this.fields.append(h("p", { class: "muted method-summary" }, method.summary));
    for (const f of fieldSpecs(method)) {
      const control = f.options
        ? h("select", { name: f.key, "data-param": f.key }, ...f.options.map((o) => h("option", { value: o, selected: o === f.value }, o)))
        : h("input", { name: f.key, "data-param": f.key, ...f.input, value: f.value });
      this.fields.append(h("label", { title: f.title }, f.label, control));
    }
  }

  private async submit(): Promise<void> {
    const data = new FormData(this.form);
    const method = findMethod(this.methods, String(data.get("method")));
    const fields: Record<string, string> = {};
    for (const field of this.fields.querySelectorAll<HTMLInputElement | HTMLSelectElement>("[data-param]"))
      fields[field.dataset.param!] = field.value;
    const strategy = method ? strategyFromFields(method, fields) : { method: String(data.get("method")) };
    const button = this.form.querySelector<HTMLButtonElement>("#submit-button")!;
    button.disabled = true;
    try {
      const name = String(data.get("name") ?? "").trim();
      const r = await api.submit({
        scene: String(data.get("scene")),
        resolution: String(data.get("resolution")).trim(),
        // As typed: a seed past 2^53 would lose digits as a number.
        seed: String(data.get("seed") || "0").trim(),
        strategy,
        // Only when given: a coordinator without names refuses the field.
        ...(name ? { name } : {}),
      });
      this.upsert(r);
      this.setMessage(`submitted ${r.id}`, false);
    } catch (e) {
      this.setMessage(e instanceof ApiError ? e.message : `cannot submit: ${(e as Error).message}`, true);
    } finally {
      button.disabled = false;
    }
  }

  private setMessage(text: string, isError: boolean): void {
    this.message.textContent = text;
    this.message.classList.toggle("error", isError);
  }

  private async load(): Promise<void> {
    try {
      const { renders } = await api.renders();
      clear(this.tbody);
      this.rows.clear();
      this.forgetThumbnails();
      this.renders.clear();
      this.order = "";
      for (const r of renders) this.upsert(r);
    } catch (e) {
      this.setMessage(`cannot load renders: ${(e as Error).message}`, true);
    }
  }

  private upsert(r: RenderSummary): void {
    this.renders.set(r.id, { ...this.renders.get(r.id), ...r });
    let row = this.rows.get(r.id);
    if (!row) {
      row = this.row(r);
      this.rows.set(r.id, row);
    }
    this.update(row, this.renders.get(r.id)!);
    this.applyView();
  }

  // The render's thumbnail, fetched again when its samples changed, at most every few
  // seconds per render (the server keeps one per render and change: thumbnail.png), and
  // again after a failed load (a 503 when the image routes are busy), even when no event
  // comes: a finished render's last thumbnail must not stay broken.
  private thumbnail(row: HTMLTableRowElement, r: RenderSummary): void {
    const img = row.querySelector<HTMLImageElement>("img.thumb")!;
    let t = this.thumbs.get(r.id);
    if (!t) this.thumbs.set(r.id, (t = { schedule: new ThumbnailSchedule(THUMBNAIL_MS), timer: null }));
    const state = t;
    if (state.timer) return;
    const wait = state.schedule.wait(r.samples_done, performance.now());
    if (wait === null) return;
    const load = () => {
      state.timer = null;
      const latest = this.renders.get(r.id) ?? r;
      const samples = latest.samples_done;
      state.schedule.fetching(samples, performance.now());
      img.onload = () => state.schedule.loaded();
      img.onerror = () => {
        state.schedule.failed();
        // Not for a page left or a row rebuilt since (dispose clears thumbs).
        if (this.thumbs.get(r.id) === state && this.rows.get(r.id) === row)
          this.thumbnail(row, this.renders.get(r.id) ?? latest);
      };
      img.src = api.thumbnailUrl(r.id, samples);
    };
    if (wait <= 0) load();
    else state.timer = setTimeout(load, wait);
  }

  private row(r: RenderSummary): HTMLTableRowElement {
    const cancel = h("button", { class: "small cancel", "data-cancel": r.id, type: "button" }, "cancel");
    cancel.addEventListener("click", async () => {
      cancel.disabled = true;
      try {
        this.upsert(await api.cancel(r.id));
      } catch (e) {
        this.setMessage((e as Error).message, true);
        cancel.disabled = false;
      }
    });
    const num = (name: string) => h("td", { class: "num", "data-col": name });
    const link = `#/render/${encodeURIComponent(r.id)}`;
    const thumb = h("img", { class: "thumb", alt: "", loading: "lazy", width: 48, height: 48 });
    thumb.addEventListener("error", () => thumb.removeAttribute("src"));
    return h(
      "tr",
      { "data-id": r.id },
      h("td", { class: "thumb-cell" }, h("a", { href: link, tabindex: -1 }, thumb)),
      h("td", { class: "name-cell" }, h("a", { href: link, class: "render-link" }, r.id), h("span", { class: "render-name muted" })),
      h("td", { class: "num live-value", "data-col": "submitted", title: r.created_ms ? new Date(r.created_ms).toLocaleString() : "" }, submitted(r.created_ms)),
      h("td", {}, r.scene, h("span", { class: "muted" }, ` ${r.width}×${r.height}`)),
      h("td", {}, r.method),
      h("td", { class: "state" }, stateBadge(r.state)),
      h("td", { class: "progress-cell" }, progressBar(r.progress, progressText(r))),
      h("td", { class: "num live-value", "data-col": "eta" }),
      num("rate"),
      num("error"),
      num("reference"),
      num("rounds"),
      num("time"),
      h("td", { class: "actions" }, cancel),
    );
  }

  private update(row: HTMLTableRowElement, r: RenderSummary): void {
    row.dataset.state = r.state;
    row.dataset.progress = r.progress.toFixed(4);
    const state = row.querySelector<HTMLElement>("td.state")!;
    state.title = r.error ?? "";
    setBadge(state.querySelector<HTMLElement>(".badge")!, r.state);
    setProgress(row.querySelector<HTMLElement>(".progress")!, r.progress, progressText(r));
    const cell = (name: string) => row.querySelector<HTMLElement>(`td[data-col="${name}"]`)!;
    // A named render shows its name first, its id as the link beside it.
    const link = row.querySelector<HTMLAnchorElement>("a.render-link")!;
    setText(link, r.name || r.id);
    setText(row.querySelector<HTMLElement>(".render-name")!, r.name ? ` ${r.id}` : "");
    if (r.state === "queued" && r.queue_position) row.dataset.queuePosition = String(r.queue_position);
    else delete row.dataset.queuePosition;
    setText(cell("eta"), etaText(r, fmt.seconds));
    this.thumbnail(row, r);
    setText(cell("rate"), fmt.count(r.samples_per_second));
    setText(cell("error"), fmt.error(r.error_estimate));
    setText(cell("reference"), fmt.error(r.error_vs_reference));
    // The mean bias where there is one, on hover: the list keeps its columns.
    cell("reference").title = r.mean_bias === null || r.mean_bias === undefined ? "" : `mean bias ${biasText(r.mean_bias, r.mean_bias_se)}`;
    setText(cell("rounds"), String(r.rounds));
    setText(cell("time"), fmt.seconds(r.seconds));
    const cancel = row.querySelector<HTMLButtonElement>("button.cancel")!;
    cancel.hidden = r.state !== "running" && r.state !== "queued";
  }

  onEvent(e: LiveEvent): void {
    if (e.type === "render") {
      for (const r of e.renders) this.upsert(r);
    } else if (e.type === "resync") {
      void this.load();
    }
  }

  // The rows' <img>s are new (a reload) or gone: every thumbnail is fetched afresh.
  private forgetThumbnails(): void {
    for (const t of this.thumbs.values()) if (t.timer) clearTimeout(t.timer);
    this.thumbs.clear();
  }

  dispose(): void {
    this.forgetThumbnails();
  }
}
