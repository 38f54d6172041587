// Workers: every worker the coordinator has heard from, where it runs (host, release), what
// it holds, how fast it traces and how many of its jobs failed; a worker silent for longer
// than --lost-seconds shows as lost.
import { api, type Worker } from "../api";
import { clear, h } from "../dom";
import * as fmt from "../format";
import type { LiveEvent } from "../live";
import { stateBadge, type Page } from "./page";

export class WorkersPage implements Page {
  el = h("section", { class: "page workers-page" });
  private tbody = h("tbody");
  private workers: Worker[] = [];
  private skew = 0; // server clock minus ours, so "last seen" does not depend on our clock
  private timer: ReturnType<typeof setInterval>;
  private empty = h("p", { class: "muted empty" }, "No workers yet: start one with aliquot worker --coordinator HOST:PORT.");

  constructor() {
    this.el.append(
      h("h1", {}, "Workers"),
      h(
        "div",
        { class: "table-wrap" },
        h(
          "table",
          { class: "workers", id: "workers-table" },
          h("thead", {}, h("tr", {}, ...["name", "host", "version", "threads", "state", "failures", "current lease", "samples/s", "samples traced", "last seen"].map((t) => h("th", {}, t)))),
          this.tbody,
        ),
      ),
      this.empty,
    );
    // Only the "last seen" text ticks; data comes from live events.
    this.timer = setInterval(() => this.show(), 1000);
    void this.load();
  }

  private async load(): Promise<void> {
    const { workers, now_ms } = await api.workers();
    this.set(workers, now_ms);
  }

  private set(workers: Worker[], nowMs: number): void {
    this.workers = workers;
    this.skew = nowMs - Date.now();
    this.show();
  }

  private show(): void {
    const now = Date.now() + this.skew;
    clear(this.tbody);
    for (const w of this.workers) {
      this.tbody.append(
        h(
          "tr",
          { "data-name": w.name, "data-state": w.state, class: w.state === "lost" ? "lost" : "" },
          h("td", {}, w.name),
          h("td", { class: "host" }, w.host || h("span", { class: "muted" }, "–")),
          h("td", { class: "version" }, w.version || h("span", { class: "muted" }, "–")),
          h("td", { class: "num" }, w.threads),
          h("td", { class: "state" }, stateBadge(w.state)),
          h("td", { class: `num failures${w.failures ? " error" : ""}` }, w.failures ?? 0),
          h("td", { class: "lease" }, w.leases.length ? w.leases.join(", ") : h("span", { class: "muted" }, "–")),
          h("td", { class: "num live-value" }, fmt.count(w.samples_per_second)),
          h("td", { class: "num live-value" }, fmt.count(w.samples_traced)),
          h("td", { class: "num live-value", title: new Date(w.last_seen_ms).toLocaleString() }, fmt.ago(w.last_seen_ms, now)),
        ),
      );
    }
    this.empty.hidden = this.workers.length > 0;
  }

  onEvent(e: LiveEvent): void {
    if (e.type === "workers") this.set(e.workers, e.now_ms);
    else if (e.type === "resync") void this.load();
  }

  dispose(): void {
    clearInterval(this.timer);
  }
}
