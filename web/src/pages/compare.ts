// Compare: renders of one scene side by side, their error against wall time and against
// samples spent, so methods are judged at equal time and at equal budget.
import { api, type RenderSummary, type RoundRow } from "../api";
import { ErrorChart, PALETTE } from "../chart";
import { clear, h } from "../dom";
import * as fmt from "../format";
import { throttle, type LiveEvent } from "../live";
import { setBadge, setText, stateBadge, type Page } from "./page";

type Metric = "error_estimate" | "error_vs_reference";

export class ComparePage implements Page {
  el = h("section", { class: "page compare-page" });
  private renders: RenderSummary[] = [];
  private rounds = new Map<string, RoundRow[]>();
  private selected = new Set<string>();
  private scene = "";
  private metric: Metric = "error_estimate";
  private sceneSelect = h("select", { id: "compare-scene" });
  private metricSelect = h(
    "select",
    { id: "compare-metric" },
    h("option", { value: "error_estimate" }, "error estimate"),
    h("option", { value: "error_vs_reference" }, "error vs reference"),
  );
  private picker = h("div", { class: "picker", id: "compare-picker" });
  private byTime = this.chart("error vs wall time", "seconds");
  private byBudget = this.chart("error vs samples (budget)", "samples");
  private note = h("p", { class: "muted" });
  private refreshPicker = throttle(() => this.showPicker(), 1000);

  constructor(query: URLSearchParams) {
    this.scene = query.get("scene") ?? "";
    for (const id of (query.get("ids") ?? "").split(",").filter(Boolean)) this.selected.add(id);
    if (query.get("metric") === "error_vs_reference") this.metric = "error_vs_reference";
    this.metricSelect.value = this.metric;
    this.byTime.el.id = "compare-time";
    this.byBudget.el.id = "compare-budget";
    this.sceneSelect.addEventListener("change", () => {
      this.scene = this.sceneSelect.value;
      this.selected.clear();
      clear(this.picker);
      this.defaultSelection();
      this.showPicker();
      void this.update();
    });
    this.metricSelect.addEventListener("change", () => {
      this.metric = this.metricSelect.value as Metric;
      this.draw();
      this.saveQuery();
    });
    this.el.append(
      h("h1", {}, "Compare"),
      h("div", { class: "card form-row" }, h("label", {}, "scene ", this.sceneSelect), h("label", {}, "error ", this.metricSelect)),
      this.picker,
      this.note,
      h("div", { class: "chart-row" }, h("div", { class: "card" }, this.byTime.el), h("div", { class: "card" }, this.byBudget.el)),
    );
    void this.load();
  }

  private chart(title: string, xLabel: string): ErrorChart {
    return new ErrorChart({ title, xLabel, yLabel: "mean abs. error", logX: true, logY: true, series: [], height: 300 });
  }

  private async load(): Promise<void> {
    const { renders } = await api.renders(1000);
    this.renders = renders;
    clear(this.picker);
    const scenes = [...new Set(renders.map((r) => r.scene))].sort();
    clear(this.sceneSelect);
    for (const s of scenes) this.sceneSelect.append(h("option", { value: s }, s));
    if (!scenes.includes(this.scene)) this.scene = scenes[0] ?? "";
    this.sceneSelect.value = this.scene;
    if (!this.selected.size) this.defaultSelection();
    this.showPicker();
    await this.update();
  }

  private ofScene(): RenderSummary[] {
    return this.renders.filter((r) => r.scene === this.scene);
  }

  private defaultSelection(): void {
    // The newest few renders of the scene that have rounds to show.
    for (const r of this.ofScene().filter((r) => r.rounds > 0).slice(0, 6)) this.selected.add(r.id);
  }

  // Checkboxes stay the same elements while their labels update (see page.ts).
  private showPicker(): void {
    const list = this.ofScene();
    const ids = new Set(list.map((r) => r.id));
    for (const label of [...this.picker.querySelectorAll<HTMLElement>("label.pick, p")])
      if (!ids.has(label.dataset.id ?? "")) label.remove();
    if (!list.length) {
      this.picker.append(h("p", { class: "muted" }, "No renders to compare yet."));
      return;
    }
    let previous: HTMLElement | null = null;
    for (const r of list) {
      let label = this.picker.querySelector<HTMLElement>(`label.pick[data-id="${r.id}"]`);
      if (!label) {
        const box = h("input", { type: "checkbox", value: r.id, checked: this.selected.has(r.id) });
        box.addEventListener("change", () => {
          if (box.checked) this.selected.add(r.id);
          else this.selected.delete(r.id);
          void this.update();
        });
        label = h("label", { class: "pick", "data-id": r.id }, box, ` ${r.id} `, h("strong", {}, r.method), h("span", { class: "info" }), stateBadge(r.state));
      }
      setText(label.querySelector<HTMLElement>(".info")!, ` ${r.width}×${r.height} · ${fmt.count(r.samples_done)} samples `);
      setBadge(label.querySelector<HTMLElement>(".badge")!, r.state);
      // Newest first, as the list comes.
      if (previous) {
        if (previous.nextSibling !== label) previous.after(label);
      } else if (this.picker.firstChild !== label) this.picker.prepend(label);
      previous = label;
    }
  }

  private async update(): Promise<void> {
    const missing = [...this.selected].filter((id) => !this.rounds.has(id));
    await Promise.all(
      missing.map(async (id) => {
        try {
          this.rounds.set(id, (await api.rounds(id)).rounds);
        } catch {
          this.selected.delete(id);
        }
      }),
    );
    this.saveQuery();
    this.draw();
  }

  private saveQuery(): void {
    const q = new URLSearchParams({ scene: this.scene, ids: [...this.selected].join(","), metric: this.metric });
    history.replaceState(null, "", `#/compare?${q}`);
  }

  private draw(): void {
    const ids = this.ofScene()
      .map((r) => r.id)
      .filter((id) => this.selected.has(id));
    const byId = new Map(this.renders.map((r) => [r.id, r]));
    const series = ids.map((id, k) => {
      const r = byId.get(id)!;
      return { label: `${id} ${r.method}`, color: PALETTE[k % PALETTE.length] };
    });
    const rows = ids.map((id) => this.rounds.get(id) ?? []);
    const y = rows.map((rs) => rs.map((r) => r[this.metric]));
    this.byTime.setSeries(
      rows.map((rs, k) => ({ x: rs.map((r) => r.seconds), y: y[k] })),
      { series },
    );
    this.byBudget.setSeries(
      rows.map((rs, k) => ({ x: rs.map((r) => r.samples_total), y: y[k] })),
      { series },
    );
    const noRef = this.metric === "error_vs_reference" && y.every((ys) => ys.every((v) => v === null));
    this.note.textContent = !ids.length
      ? "Pick renders above."
      : noRef
        ? "None of these renders has a reference: submit with --reference to measure the true error."
        : "";
  }

  onEvent(e: LiveEvent): void {
    if (e.type === "render") {
      let added = false;
      for (const r of e.renders) {
        const i = this.renders.findIndex((x) => x.id === r.id);
        if (i >= 0) this.renders[i] = r;
        else {
          this.renders.unshift(r);
          added = true;
        }
      }
      if (added && !this.scene) void this.load();
      else this.refreshPicker();
    } else if (e.type === "round") {
      let touched = false;
      for (const r of e.rounds) {
        const list = this.rounds.get(r.id);
        if (list && r.position === list.length) {
          list.push(r);
          touched = touched || this.selected.has(r.id);
        } else if (list && r.position > list.length) {
          this.rounds.delete(r.id); // missed some: fetch them all again
          touched = true;
        }
      }
      if (touched) void this.update();
    } else if (e.type === "resync") {
      this.rounds.clear();
      void this.load();
    }
  }

  dispose(): void {
    this.refreshPicker.cancel();
    this.byTime.destroy();
    this.byBudget.destroy();
  }
}
