// Live updates from GET /api/events (server-sent events). The server sends at most a few
// small messages per second saying what changed; pages fetch what they show. After a
// reconnect, or when the server says we fell behind, listeners get "resync" and refetch.
import type { RenderSummary, RoundRow, Worker } from "./api";

export type LiveEvent =
  | { type: "hello"; now_ms: number; storage_warning?: string }
  | { type: "storage"; storage_warning: string }
  | { type: "render"; renders: RenderSummary[] }
  | { type: "round"; rounds: (RoundRow & { id: string; position: number })[] }
  | { type: "workers"; workers: Worker[]; now_ms: number }
  | { type: "resync" };

export type Listener = (e: LiveEvent) => void;

/** What Live needs of EventSource; tests pass a fake. */
export interface EventSourceLike {
  readonly readyState: number;
  onopen: ((e: Event) => unknown) | null;
  onerror: ((e: Event) => unknown) | null;
  onmessage: ((m: MessageEvent) => unknown) | null;
  close(): void;
}

/** EventSource.CLOSED: the browser gave up and will not reconnect by itself. */
const CLOSED = 2;

/**
 * How long to wait before reconnecting after the browser gave up on the stream (the
 * server refused it, e.g. 503 when too many streams are open): 2 s doubling to 60 s, with
 * up to a quarter more at random so that many pages refused at once do not come back at
 * once.
 */
export function reconnectDelay(failures: number, random = Math.random): number {
  const base = Math.min(60000, 2000 * 2 ** Math.max(0, failures - 1));
  return Math.round(base * (1 + 0.25 * random()));
}

export class Live {
  private source: EventSourceLike | null = null;
  private listeners = new Set<Listener>();
  private everOpen = false;
  private lost = false;
  private failures = 0;
  private timer: ReturnType<typeof setTimeout> | null = null;
  status: "connecting" | "live" | "reconnecting" = "connecting";
  onStatus: (s: Live["status"]) => void = () => {};
  /**
   * Runs when the server refuses a stream. EventSource does not say why, so the page asks
   * elsewhere whether it is still signed in (a 401 here means it is not).
   */
  onRefused: () => void = () => {};

  constructor(
    private readonly url = "/api/events",
    private readonly open: (url: string) => EventSourceLike = (u) => new EventSource(u),
  ) {}

  start(): void {
    const source = this.open(this.url);
    this.source = source;
    source.onopen = () => {
      this.failures = 0;
      this.setStatus("live");
      if (this.everOpen && this.lost) this.emit({ type: "resync" });
      this.everOpen = true;
      this.lost = false;
    };
    source.onerror = () => {
      this.lost = true;
      this.setStatus("reconnecting");
      // A dropped stream is retried by the browser ("retry: 2000"); a refused one (any
      // status but 200) is closed for good, so we come back later ourselves, waiting
      // longer after each refusal rather than hammering a busy server.
      if (source.readyState !== CLOSED || this.source !== source) return;
      source.close();
      this.source = null;
      this.failures++;
      this.timer = setTimeout(() => {
        this.timer = null;
        this.start();
      }, reconnectDelay(this.failures));
      // Last: it may stop this stream for good (signed out), which cancels the retry.
      this.onRefused();
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
    if (this.timer) clearTimeout(this.timer);
    this.timer = null;
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
 * rounds finish. Timed by the monotonic clock: the wall clock (Date.now) may be set back
 * while the page runs, and a throttle timed by it would then run early.
 */
export function throttle(fn: () => void, ms: number): { (): void; cancel(): void } {
  let last = -Infinity;
  let timer: ReturnType<typeof setTimeout> | null = null;
  const run = () => {
    timer = null;
    // Timed after `fn`'s synchronous part, which makes its fetch calls: timed before it,
    // a slow first call (four fetches on a loaded page) could put the next run's fetches
    // less than `ms` after this run's last one. `finally`, so a run that throws still
    // counts and a failing `fn` is not called faster than once per `ms`.
    try {
      fn();
    } finally {
      last = performance.now();
    }
  };
  const call = () => {
    if (timer) return;
    const wait = last + ms - performance.now();
    if (wait <= 0) run();
    else timer = setTimeout(run, wait);
  };
  call.cancel = () => {
    if (timer) clearTimeout(timer);
    timer = null;
  };
  return call;
}
