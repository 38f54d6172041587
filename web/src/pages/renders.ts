// Renders: every render with its progress and error, a form to submit one, cancel buttons.
import { api, ApiError, type RenderSummary, type SceneList } from "../api";
import { clear, h } from "../dom";
import * as fmt from "../format";
import type { LiveEvent } from "../live";
import { progressBar, setBadge, setProgress, setText, stateBadge, type Page } from "./page";

// The parameters the form offers per method, with the server's defaults filled in.
const METHOD_FIELDS: Record<string, { key: string; label: string; step?: string }[]> = {
  uniform: [{ key: "spp", label: "samples per pixel" }],
  dammertz: [
    { key: "max_variance", label: "max variance V", step: "any" },
    { key: "samples_per_iteration", label: "samples per iteration S" },
    { key: "split_factor", label: "split factor", step: "any" },
    { key: "min_bucket_size", label: "min bucket size" },
    { key: "max_spp", label: "max spp (0: default)" },
  ],
  adaptive: [
    { key: "spp", label: "budget (spp x pixels)" },
    { key: "initial_spp", label: "initial spp" },
    { key: "max_variance", label: "max variance", step: "any" },
    { key: "alpha", label: "alpha", step: "any" },
    { key: "bucket_size", label: "bucket size" },
  ],
  optimal: [
    { key: "spp", label: "budget (spp x pixels)" },
    { key: "min_spp", label: "min spp" },
    { key: "max_spp", label: "max spp (0: default)" },
    { key: "sigma_prior", label: "sigma prior, samples (0: off)" },
    { key: "sigma_radius", label: "sigma pool radius (0: own pixel)" },
    { key: "floor_fraction", label: "pilot and floor, share of mean spp", step: "any" },
    { key: "steer_rounds", label: "steered rounds after the pilot (0: doubling)" },
    { key: "plan_ahead", label: "plan ahead after rounds of at most this share (0: never)", step: "any" },
  ],
  "optimal-time": [
    { key: "spp", label: "budget (spp x pixels)" },
    { key: "min_spp", label: "min spp" },
    { key: "max_spp", label: "max spp (0: default)" },
    { key: "floor_fraction", label: "pilot and floor, share of mean spp", step: "any" },
    { key: "steer_rounds", label: "steered rounds after the pilot (0: doubling)" },
    { key: "plan_ahead", label: "plan ahead after rounds of at most this share (0: never)", step: "any" },
  ],
  cycles: [
    { key: "noise_threshold", label: "noise threshold", step: "any" },
    { key: "adaptive_min_samples", label: "min samples (0: automatic)" },
    { key: "adaptive_step", label: "check every N samples" },
    { key: "max_spp", label: "max spp (0: default)" },
  ],
};

export function progressText(r: RenderSummary): string {
  if (r.buckets_total && r.state !== "done")
    return `${r.buckets_converged ?? 0}/${r.buckets_total} buckets converged · ${fmt.percent(r.progress)}`;
  // Dammertz's planned samples are only a cap: it stops where its buckets converge.
  if (r.method === "dammertz") return `${fmt.count(r.samples_done)} samples · ${fmt.percent(r.progress)}`;
  const planned = r.samples_planned ? ` / ${fmt.count(r.samples_planned)}` : "";
  return `${fmt.count(r.samples_done)}${planned} · ${fmt.percent(r.progress)}`;
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

  constructor() {
    this.el.append(
      h("h1", {}, "Renders"),
      this.buildForm(),
      h(
        "div",
        { class: "table-wrap" },
        h(
          "table",
          { class: "renders", id: "renders-table" },
          h(
            "thead",
            {},
            h(
              "tr",
              {},
              ...["render", "scene", "method", "state", "progress", "samples/s", "error estimate", "error vs reference", "rounds", "time", ""].map(
                (t) => h("th", {}, t),
              ),
            ),
          ),
          this.tbody,
        ),
      ),
      this.empty,
    );
    void this.load();
    void this.loadScenes();
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
      this.scenes = await api.scenes();
    } catch (e) {
      this.setMessage(`cannot load scenes: ${(e as Error).message}`, true);
      return;
    }
    const scene = this.form.querySelector<HTMLSelectElement>("#submit-scene")!;
    const method = this.form.querySelector<HTMLSelectElement>("#submit-method")!;
    for (const s of this.scenes.scenes) scene.append(h("option", { value: s }, s));
    for (const m of this.scenes.methods) method.append(h("option", { value: m }, m));
    this.showFields();
  }

  private showFields(): void {
    clear(this.fields);
    const method = this.form.querySelector<HTMLSelectElement>("#submit-method")!.value;
    const defaults = this.scenes?.defaults ?? {};
    for (const f of METHOD_FIELDS[method] ?? []) {
      const value = f.key === "spp" ? 64 : defaults[f.key] ?? 0;
      this.fields.append(
        h("label", {}, f.label, h("input", { name: f.key, "data-param": f.key, type: "number", min: 0, step: f.step ?? "1", value: String(value) })),
      );
    }
  }

  private async submit(): Promise<void> {
    const data = new FormData(this.form);
    const strategy: Record<string, number | string> = { method: String(data.get("method")) };
    for (const input of this.fields.querySelectorAll<HTMLInputElement>("input[data-param]")) {
      if (input.value !== "") strategy[input.dataset.param!] = Number(input.value);
    }
    const button = this.form.querySelector<HTMLButtonElement>("#submit-button")!;
    button.disabled = true;
    try {
      const r = await api.submit({
        scene: String(data.get("scene")),
        resolution: String(data.get("resolution")).trim(),
        // As typed: a seed past 2^53 would lose digits as a number.
        seed: String(data.get("seed") || "0").trim(),
        strategy,
      });
      this.upsert(r, true);
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
      // Newest first from the server; append keeps that order.
      for (const r of renders) this.upsert(r, false);
    } catch (e) {
      this.setMessage(`cannot load renders: ${(e as Error).message}`, true);
    }
  }

  private upsert(r: RenderSummary, newest: boolean): void {
    this.renders.set(r.id, r);
    let row = this.rows.get(r.id);
    if (!row) {
      row = this.row(r);
      if (newest) this.tbody.prepend(row);
      else this.tbody.append(row);
      this.rows.set(r.id, row);
    }
    this.update(row, r);
    this.empty.hidden = this.rows.size > 0;
  }

  private row(r: RenderSummary): HTMLTableRowElement {
    const cancel = h("button", { class: "small cancel", "data-cancel": r.id, type: "button" }, "cancel");
    cancel.addEventListener("click", async () => {
      cancel.disabled = true;
      try {
        this.upsert(await api.cancel(r.id), false);
      } catch (e) {
        this.setMessage((e as Error).message, true);
        cancel.disabled = false;
      }
    });
    const num = (name: string) => h("td", { class: "num", "data-col": name });
    return h(
      "tr",
      { "data-id": r.id },
      h("td", {}, h("a", { href: `#/render/${encodeURIComponent(r.id)}` }, r.id)),
      h("td", {}, r.scene, h("span", { class: "muted" }, ` ${r.width}×${r.height}`)),
      h("td", {}, r.method),
      h("td", { class: "state" }, stateBadge(r.state)),
      h("td", { class: "progress-cell" }, progressBar(r.progress, progressText(r))),
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
    setText(cell("rate"), fmt.count(r.samples_per_second));
    setText(cell("error"), fmt.error(r.error_estimate));
    setText(cell("reference"), fmt.error(r.error_vs_reference));
    setText(cell("rounds"), String(r.rounds));
    setText(cell("time"), fmt.seconds(r.seconds));
    const cancel = row.querySelector<HTMLButtonElement>("button.cancel")!;
    cancel.hidden = r.state !== "running" && r.state !== "queued";
  }

  onEvent(e: LiveEvent): void {
    if (e.type === "render") {
      for (const r of e.renders) this.upsert(r, !this.rows.has(r.id));
    } else if (e.type === "resync") {
      void this.load();
    }
  }
}
