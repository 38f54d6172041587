import { afterEach, describe, expect, it, vi } from "vitest";
import { Live, reconnectDelay, throttle, type EventSourceLike } from "./live";

describe("throttle", () => {
  afterEach(() => vi.useRealTimers());
  it("runs at once, then folds calls within the interval into one trailing run", () => {
    vi.useFakeTimers({ toFake: ["setTimeout", "clearTimeout", "Date", "performance"] });
    let runs = 0;
    const t = throttle(() => runs++, 1000);
    t();
    expect(runs).toBe(1);
    t();
    t();
    t();
    expect(runs).toBe(1);
    vi.advanceTimersByTime(999);
    expect(runs).toBe(1);
    vi.advanceTimersByTime(1);
    expect(runs).toBe(2);
    vi.advanceTimersByTime(5000);
    expect(runs).toBe(2);
  });

  it("spaces runs from the end of the last run's synchronous part, where its fetches are made", () => {
    vi.useFakeTimers({ toFake: ["setTimeout", "clearTimeout", "Date", "performance"] });
    const fetched: number[] = [];
    const t = throttle(() => {
      // The first run's fetch calls take 15 ms of a loaded main thread; the last is made then.
      if (!fetched.length) vi.advanceTimersByTime(15);
      fetched.push(performance.now());
    }, 1000);
    t();
    t();
    vi.advanceTimersByTime(2000);
    expect(fetched.length).toBe(2);
    expect(fetched[1] - fetched[0]).toBeGreaterThanOrEqual(1000);
  });

  it("counts a run that throws, so a failing call is not repeated faster than the interval", () => {
    vi.useFakeTimers({ toFake: ["setTimeout", "clearTimeout", "Date", "performance"] });
    let runs = 0;
    const t = throttle(() => {
      runs++;
      throw new Error("failed");
    }, 1000);
    expect(() => t()).toThrow("failed");
    t();
    expect(runs).toBe(1);
    vi.advanceTimersByTime(999);
    expect(runs).toBe(1);
  });
});

class FakeSource implements EventSourceLike {
  readyState = 0;
  onopen: ((e: Event) => unknown) | null = null;
  onerror: ((e: Event) => unknown) | null = null;
  onmessage: ((m: MessageEvent) => unknown) | null = null;
  closed = false;
  close(): void {
    this.closed = true;
    this.readyState = 2;
  }
  /** What a browser does when the server answers anything but 200 (e.g. 503). */
  refuse(): void {
    this.readyState = 2;
    this.onerror?.({} as Event);
  }
  accept(): void {
    this.readyState = 1;
    this.onopen?.({} as Event);
  }
}

describe("Live", () => {
  afterEach(() => vi.useRealTimers());

  it("backs off after refused streams instead of reconnecting at once", () => {
    vi.useFakeTimers();
    const sources: FakeSource[] = [];
    const live = new Live("/api/events", () => {
      const s = new FakeSource();
      sources.push(s);
      return s;
    });
    live.start();
    expect(sources.length).toBe(1);

    sources[0].refuse();
    expect(live.status).toBe("reconnecting");
    vi.advanceTimersByTime(1999);
    expect(sources.length).toBe(1); // not before 2 s
    vi.advanceTimersByTime(600);
    expect(sources.length).toBe(2);

    sources[1].refuse(); // the second refusal waits at least twice as long
    vi.advanceTimersByTime(3999);
    expect(sources.length).toBe(2);
    vi.advanceTimersByTime(1100);
    expect(sources.length).toBe(3);

    sources[2].accept();
    expect(live.status).toBe("live");
    live.stop();
    expect(sources[2].closed).toBe(true);
  });

  it("leaves a dropped stream to the browser's own retry and stops cleanly", () => {
    vi.useFakeTimers();
    const sources: FakeSource[] = [];
    const live = new Live("/api/events", () => {
      const s = new FakeSource();
      sources.push(s);
      return s;
    });
    const events: string[] = [];
    live.subscribe((e) => events.push(e.type));
    live.start();
    sources[0].accept();
    sources[0].readyState = 0; // CONNECTING: the browser retries by itself
    sources[0].onerror?.({} as Event);
    vi.advanceTimersByTime(60000);
    expect(sources.length).toBe(1);
    sources[0].accept();
    expect(events).toEqual(["resync"]);

    sources[0].refuse();
    live.stop(); // a pending reconnect is cancelled
    vi.advanceTimersByTime(120000);
    expect(sources.length).toBe(1);
  });

  it("tells the page of each refusal, which may stop it for good", () => {
    vi.useFakeTimers();
    const sources: FakeSource[] = [];
    const live = new Live("/api/events", () => {
      const s = new FakeSource();
      sources.push(s);
      return s;
    });
    let refusals = 0;
    live.onRefused = () => refusals++;
    live.start();
    sources[0].accept();
    sources[0].readyState = 0; // dropped, not refused: the browser retries
    sources[0].onerror?.({} as Event);
    expect(refusals).toBe(0);
    sources[0].refuse();
    expect(refusals).toBe(1);
    live.onRefused = () => live.stop(); // what a 401 leads to: the sign-in view
    vi.advanceTimersByTime(2600);
    sources[1].refuse();
    vi.advanceTimersByTime(120000);
    expect(sources.length).toBe(2);
  });

  it("waits 2 s doubling up to a minute, with at most a quarter more", () => {
    expect(reconnectDelay(1, () => 0)).toBe(2000);
    expect(reconnectDelay(2, () => 0)).toBe(4000);
    expect(reconnectDelay(3, () => 0.999)).toBeLessThanOrEqual(10000);
    expect(reconnectDelay(20, () => 0)).toBe(60000);
    expect(reconnectDelay(20, () => 1)).toBe(75000);
  });
});
