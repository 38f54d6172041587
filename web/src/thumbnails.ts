// When the renders page fetches a render's thumbnail: again when its samples changed, at
// most every intervalMs, and again after a failed load (the image routes answer 503 when
// too many images are being made), waiting longer after each failure in a row. An <img>
// cannot read the answer's Retry-After, so the wait doubles instead, up to maxRetryMs.
export class ThumbnailSchedule {
  private samples = -1; // the samples of the thumbnail shown or being loaded
  private at = -Infinity; // when it was asked for
  private failures = 0; // loads failed in a row

  constructor(
    private readonly intervalMs: number,
    private readonly maxRetryMs = 60_000,
  ) {}

  // Milliseconds to wait before fetching the thumbnail of `samplesDone` samples (0: now),
  // or null when the one shown or being loaded is of those samples.
  wait(samplesDone: number, now: number): number | null {
    if (samplesDone === 0 || samplesDone === this.samples) return null;
    const spacing = Math.min(this.intervalMs * 2 ** this.failures, this.maxRetryMs);
    return Math.max(0, this.at + spacing - now);
  }

  fetching(samples: number, now: number): void {
    this.samples = samples;
    this.at = now;
  }

  loaded(): void {
    this.failures = 0;
  }

  // The load failed: the samples are not shown, so the next wait() fetches them again.
  failed(): void {
    this.samples = -1;
    this.failures += 1;
  }
}
