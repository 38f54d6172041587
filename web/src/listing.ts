// The renders list's sort and filter, kept apart from the page so that it is tested alone:
// what a Deadline Monitor or Flamenco user expects of a job list.
import type { RenderSummary } from "./api";
import { etaSeconds } from "./eta";

export type SortKey = "created" | "name" | "scene" | "method" | "state" | "progress" | "eta" | "error" | "time";

export interface RenderFilter {
  state: string; // "" for any; "active" for queued or running
  method: string;
  scene: string;
  text: string; // part of the name or id, any case
}

export const NO_FILTER: RenderFilter = { state: "", method: "", scene: "", text: "" };

export function matches(r: RenderSummary, f: RenderFilter): boolean {
  if (f.state === "active" ? r.state !== "queued" && r.state !== "running" : f.state && r.state !== f.state) return false;
  if (f.method && r.method !== f.method) return false;
  if (f.scene && r.scene !== f.scene) return false;
  const text = f.text.trim().toLowerCase();
  if (text && !`${r.name ?? ""} ${r.id}`.toLowerCase().includes(text)) return false;
  return true;
}

// Queued first in their queue's order, then running, then the finished ones: the order
// in which they need a look.
const STATE_ORDER: Record<string, number> = { queued: 0, running: 1, failed: 2, cancelled: 3, done: 4 };

function key(r: RenderSummary, k: SortKey): number | string {
  switch (k) {
    case "created":
      return r.created_ms;
    case "name":
      return (r.name || r.id).toLowerCase();
    case "scene":
      return r.scene;
    case "method":
      return r.method;
    case "state":
      return (STATE_ORDER[r.state] ?? 9) * 1e6 + (r.queue_position ?? 0);
    case "progress":
      return r.progress;
    case "eta":
      // Renders without an ETA sort after those with one, whichever the direction.
      return etaSeconds(r) ?? Number.POSITIVE_INFINITY;
    case "error":
      return r.error_estimate ?? Number.POSITIVE_INFINITY;
    case "time":
      return r.seconds;
  }
}

/** A sorted copy; ties keep the newest first (the server's order), so a sort is stable. */
export function sortRenders(renders: RenderSummary[], k: SortKey, descending: boolean): RenderSummary[] {
  return renders
    .map((r, i) => ({ r, i, v: key(r, k) }))
    .sort((a, b) => {
      const inf = (v: number | string) => v === Number.POSITIVE_INFINITY;
      if (inf(a.v) !== inf(b.v)) return inf(a.v) ? 1 : -1;
      let c = a.v < b.v ? -1 : a.v > b.v ? 1 : 0;
      if (descending) c = -c;
      if (c === 0) c = b.r.created_ms - a.r.created_ms || (a.r.id < b.r.id ? 1 : a.r.id > b.r.id ? -1 : 0);
      return c;
    })
    .map((x) => x.r);
}

/** The filter and sort as the address keeps them (#/renders?state=done&sort=eta). */
export function viewFromQuery(q: URLSearchParams): { filter: RenderFilter; sort: SortKey; descending: boolean } {
  const sorts: SortKey[] = ["created", "name", "scene", "method", "state", "progress", "eta", "error", "time"];
  const sort = sorts.find((s) => s === q.get("sort")) ?? "created";
  return {
    filter: { state: q.get("state") ?? "", method: q.get("method") ?? "", scene: q.get("scene") ?? "", text: q.get("q") ?? "" },
    sort,
    descending: q.has("dir") ? q.get("dir") !== "asc" : sort === "created",
  };
}
