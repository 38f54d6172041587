// A render's log (GET /api/renders/{id}/events) as lines for its page: whatever fields an
// event has besides its time and kind are shown as key=value, so a new field needs no
// change here.
import type { RenderEvent } from "./api";

export interface EventLine {
  timeMs: number | null;
  kind: string;
  detail: string;
}

const TIME_KEYS = ["at_ms", "time_ms", "unix_ms", "ms", "time", "at"];
const KIND_KEYS = ["event", "kind", "type"];
const HIDDEN = new Set([...TIME_KEYS, ...KIND_KEYS, "seq", "render", "id", "fields"]);

function timeOf(e: RenderEvent): number | null {
  for (const k of TIME_KEYS) {
    const v = e[k];
    if (typeof v === "number" && Number.isFinite(v)) return v;
    if (typeof v === "string") {
      const t = Date.parse(v);
      if (Number.isFinite(t)) return t;
    }
  }
  return null;
}

function text(v: unknown): string {
  if (typeof v === "string") return /[\s"=]/.test(v) ? JSON.stringify(v) : v;
  if (typeof v === "number" || typeof v === "boolean") return String(v);
  return JSON.stringify(v);
}

export function eventLines(body: unknown): EventLine[] {
  const list = Array.isArray(body) ? body : body && typeof body === "object" ? (body as { events?: unknown }).events : null;
  if (!Array.isArray(list)) return [];
  return list
    .filter((e): e is RenderEvent => !!e && typeof e === "object")
    .map((e) => {
      const kind = KIND_KEYS.map((k) => e[k]).find((v) => typeof v === "string") as string | undefined;
      // Fields may come flat or nested under "fields".
      const fields: Record<string, unknown> = { ...e, ...(e.fields && typeof e.fields === "object" ? (e.fields as object) : {}) };
      const detail = Object.entries(fields)
        .filter(([k]) => !HIDDEN.has(k))
        .map(([k, v]) => `${k}=${text(v)}`)
        .join(" ");
      return { timeMs: timeOf(e), kind: kind ?? "event", detail };
    });
}
