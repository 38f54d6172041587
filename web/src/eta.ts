// How long a render has left, as the CLI's `status` says it ("eta"), for the renders list
// and a render's page. Null when there is nothing to estimate: not running, nothing merged
// yet, or no rate measured.
import type { RenderSummary } from "./api";

type EtaInput = Pick<
  RenderSummary,
  "state" | "method" | "samples_done" | "samples_planned" | "samples_per_second" | "seconds" | "progress" | "buckets_total"
>;

export function etaSeconds(r: EtaInput): number | null {
  if (r.state !== "running" || r.samples_done <= 0) return null;
  // Dammertz's planned samples are a cap and bucket methods stop where their buckets
  // converge: their progress (converged share) is the better clock.
  const byProgress = r.method === "dammertz" || (r.buckets_total ?? 0) > 0;
  if (!byProgress && r.samples_planned > r.samples_done && r.samples_per_second > 0)
    return (r.samples_planned - r.samples_done) / r.samples_per_second;
  if (r.progress > 0 && r.progress < 1 && r.seconds > 0) return (r.seconds * (1 - r.progress)) / r.progress;
  return null;
}

/** "42 s", "3 min 5 s"; a queued render says its place instead. */
export function etaText(r: EtaInput & Pick<RenderSummary, "queue_position">, seconds: (s: number) => string): string {
  if (r.state === "queued") return r.queue_position ? `queued #${r.queue_position}` : "queued";
  const left = etaSeconds(r);
  return left === null ? "–" : seconds(left);
}
