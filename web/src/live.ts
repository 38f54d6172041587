// Live updates from GET /api/events (server-sent events). The server sends at most a few
// small messages per second saying what changed; pages fetch what they show. After a
// reconnect, or when the server says we fell behind, listeners get "resync" and refetch.
import type { RenderSummary, RoundRow, Worker } from "./api";

export type LiveEvent =
  | { type: "hello"; now_ms: number }
  | { type: "render"; renders: RenderSummary[] }
  | { type: "round"; rounds: (RoundRow & { id: string; position: number })[] }
  | { type: "workers"; workers: Worker[]; now_ms: number }
  | { type: "resync" };

export type Listener = (e: LiveEvent) => void;

export class Live {
  private source: EventSource | null = null;
  private listeners = new Set<Listener>();
  private everOpen = false;
  private lost = false;
  status: "connecting" | "live" | "reconnecting" = "connecting";
  onStatus: (s: Live["status"]) => void = () => {};

  constructor(private readonly url = "/api/events") {}

  start(): void {
    const source = new EventSource(this.url);
    this.source = source;
    source.onopen = () => {
      this.setStatus("live");
      if (this.everOpen && this.lost) this.emit({ type: "resync" });
      this.everOpen = true;
      this.lost = false;
    };
    source.onerror = () => {
      this.lost = true;
      this.setStatus("reconnecting"); // EventSource retries by itself ("retry: 2000")
    };
    source.onmessage = (m) => {
      let e: LiveEvent;
      try {
        e = JSON.parse(m.data) as LiveEvent;
      } catch {
        return;
      }
      this.emit(e);
    };
  }

  stop(): void {
    this.source?.close();
    this.source = null;
  }

  subscribe(fn: Listener): () => void {
    this.listeners.add(fn);
    return () => this.listeners.delete(fn);
  }

  private emit(e: LiveEvent): void {
    for (const fn of [...this.listeners]) {
      try {
        fn(e);
      } catch (err) {
        console.error("live listener failed", err);
      }
    }
  }

  private setStatus(s: Live["status"]): void {
    this.status = s;
    this.onStatus(s);
  }
}

/**
 * Runs `fn` at most once per `ms`: the first call at once, later ones folded into one
 * trailing call. What keeps a page from fetching faster than once a second however many
 * rounds finish.
 */
export function throttle(fn: () => void, ms: number): { (): void; cancel(): void } {
  let last = 0;
  let timer: ReturnType<typeof setTimeout> | null = null;
  const run = () => {
    timer = null;
    last = Date.now();
    fn();
  };
  const call = () => {
    if (timer) return;
    const wait = last + ms - Date.now();
    if (wait <= 0) run();
    else timer = setTimeout(run, wait);
  };
  call.cancel = () => {
    if (timer) clearTimeout(timer);
    timer = null;
  };
  return call;
}
