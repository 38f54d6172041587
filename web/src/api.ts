// The coordinator's JSON API (docs/API.md) as typed calls. Every failure becomes an
// ApiError carrying the server's own message; a 401 (no or a stale session cookie) also
// tells whoever listens through onUnauthenticated, so that any call can bring up sign-in.

export interface RenderSummary {
  id: string;
  scene: string;
  method: string;
  state: "queued" | "running" | "done" | "cancelled" | "failed";
  width: number;
  height: number;
  // A decimal string: seeds are 64-bit, beyond what a JavaScript number holds exactly.
  seed: string;
  samples_done: number;
  samples_planned: number;
  rounds: number;
  seconds: number;
  samples_per_second: number;
  error_estimate: number | null;
  error_vs_reference: number | null;
  /** The last round's mean bias against the reference (a fraction) and its SE; null
   * without a reference or a bias, absent from a coordinator older than them. */
  mean_bias?: number | null;
  mean_bias_se?: number | null;
  created_ms: number;
  finished_ms?: number;
  progress: number;
  error?: string;
  buckets_converged?: number;
  buckets_total?: number;
  /** What `submit --name` or the form named it; absent or "" when unnamed. */
  name?: string;
  /** While queued (no job leased yet): 1 = next to start. */
  queue_position?: number;
  priority?: number;
}

/** One line of a render's log (GET /api/renders/{id}/events). */
export interface RenderEvent {
  time_ms?: number;
  event?: string;
  message?: string;
  [key: string]: unknown;
}

export interface RenderDetail extends RenderSummary {
  strategy: Record<string, unknown>;
  outcome: Record<string, unknown>;
  rays: number;
}

export interface RoundRow {
  index: number;
  samples_in_round: number;
  samples_total: number;
  seconds: number;
  error_estimate: number | null;
  error_vs_reference: number | null;
  mean_bias: number | null;
  mean_bias_se: number | null;
}

type RoundCells = [number, number, number, number, number | null, number | null, (number | null)?, (number | null)?];

/** A row of GET /api/renders/{id}/rounds; an older coordinator's rows end before the bias. */
export function roundFromRow(row: RoundCells): RoundRow {
  const [index, samples_in_round, samples_total, seconds, error_estimate, error_vs_reference] = row;
  const mean_bias = row[6] ?? null;
  const mean_bias_se = row[7] ?? null;
  return { index, samples_in_round, samples_total, seconds, error_estimate, error_vs_reference, mean_bias, mean_bias_se };
}

/** GET /api/renders/{id}/rounds: rows in the order of `columns`. */
interface RoundPage {
  columns: string[];
  rows: RoundCells[];
  count: number;
  since: number;
  next: number | null;
}

export interface Worker {
  name: string;
  threads: number;
  state: "idle" | "busy" | "lost";
  leases: string[];
  samples_traced: number;
  samples_per_second: number;
  last_seen_ms: number;
  /** What the worker said when it registered: its machine and its release. */
  host?: string;
  version?: string;
  /** Jobs it reported failed. */
  failures?: number;
}

export interface PixelMap {
  kind: "spp" | "error";
  width: number;
  height: number;
  image_width: number;
  image_height: number;
  lo: number;
  hi: number;
  mean: number;
  max: number;
  data: string; // base64, one byte per cell: lo + (hi - lo) * byte / 255
}

/** [x, y, width, height, error, converged] */
export type BucketRow = [number, number, number, number, number | null, 0 | 1];

export interface Buckets {
  id: string;
  width: number;
  height: number;
  converged: number;
  converged_area: number;
  buckets: BucketRow[];
}

export interface SceneList {
  scenes: string[];
  methods: string[];
  defaults: Record<string, number | string>;
}

/** One parameter of a method (GET /api/methods). */
export interface ParamInfo {
  key: string;
  kind: "whole" | "number" | "word";
  default: number | string;
  /** The bounds in words, as the server's refusal says them. */
  bounds: string;
  help: string;
  min?: number;
  max?: number;
  min_exclusive?: boolean;
  max_exclusive?: boolean;
  /** kind "word": the values allowed. */
  values?: string[];
}

export interface MethodInfo {
  name: string;
  summary: string;
  /** False for oracle: its sigma is given in-process, never to a coordinator. */
  submittable: boolean;
  parameters: ParamInfo[];
}

export interface Study {
  source: string;
  name: string;
  title: string;
  report: string;
  files: string[];
}

export interface SubmitRequest {
  scene: string;
  resolution: string;
  seed: string;
  strategy: Record<string, number | string>;
  name?: string;
}

export class ApiError extends Error {
  constructor(
    message: string,
    readonly status: number,
  ) {
    super(message);
  }
}

let unauthenticated: () => void = () => {};

/** Sets what runs whenever the API answers 401: the page is not, or no longer, signed in. */
export function onUnauthenticated(fn: () => void): void {
  unauthenticated = fn;
}

async function parse<T>(res: Response): Promise<T> {
  const text = await res.text();
  let body: unknown = null;
  try {
    body = text ? JSON.parse(text) : null;
  } catch {
    /* not JSON: use the text */
  }
  if (!res.ok) {
    const message =
      body && typeof body === "object" && "error" in body
        ? String((body as { error: unknown }).error)
        : text || res.statusText;
    if (res.status === 401) unauthenticated();
    throw new ApiError(message, res.status);
  }
  return body as T;
}

export async function getJSON<T>(path: string): Promise<T> {
  return parse<T>(await fetch(path, { cache: "no-store" }));
}

export async function postJSON<T>(path: string, body?: unknown): Promise<T> {
  return parse<T>(
    await fetch(path, {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      // Every POST is JSON, even one without fields (the server refuses other types).
      body: JSON.stringify(body ?? {}),
    }),
  );
}

export async function patchJSON<T>(path: string, body: unknown): Promise<T> {
  return parse<T>(
    await fetch(path, { method: "PATCH", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) }),
  );
}

export async function deleteJSON<T>(path: string): Promise<T> {
  return parse<T>(
    await fetch(path, { method: "DELETE", headers: { "Content-Type": "application/json" }, body: "{}" }),
  );
}

const enc = encodeURIComponent;

export const api = {
  /** Answers only when the page is signed in (or sends a token): 401 otherwise. */
  session: () => getJSON<{ signed_in: boolean }>("/api/session"),
  /** Sets the session cookie (HttpOnly: this page never sees it again). */
  signIn: (token: string) => postJSON<{ ok: boolean }>("/api/session", { token }),
  signOut: () => deleteJSON<{ ok: boolean }>("/api/session"),
  renders: (limit = 200) =>
    getJSON<{ renders: RenderSummary[]; now_ms: number }>(`/api/renders?limit=${limit}`),
  render: (id: string) => getJSON<RenderDetail>(`/api/renders/${enc(id)}`),
  submit: (req: SubmitRequest) => postJSON<RenderDetail>("/api/renders", req),
  cancel: (id: string) => postJSON<RenderDetail>(`/api/renders/${enc(id)}/cancel`),
  setPriority: (id: string, priority: number) => patchJSON<RenderDetail>(`/api/renders/${enc(id)}`, { priority }),
  /** Deletes a finished render, its files and rows (204). */
  remove: (id: string) => deleteJSON<null>(`/api/renders/${enc(id)}`),
  /** The render's log; an ApiError with status 404 from a coordinator without one. */
  events: (id: string) => getJSON<{ events: RenderEvent[] }>(`/api/renders/${enc(id)}/events`),
  thumbnailUrl: (id: string, version: number) => `/api/renders/${enc(id)}/thumbnail.png?v=${version}`,
  exrUrl: (id: string) => `/api/renders/${enc(id)}/image.exr`,
  /** The whole image as an 8-bit sRGB PNG at the render's own size. */
  pngUrl: (id: string, width: number, height: number, exposure = 0) =>
    `/api/renders/${enc(id)}/preview.png?exposure=${exposure}&size=${Math.min(8192, Math.max(16, width, height))}`,
  /** Every round from `since` on, following the server's pages of up to 1000. */
  rounds: async (id: string, since = 0): Promise<{ rounds: RoundRow[]; count: number }> => {
    const out: RoundRow[] = [];
    let next: number | null = since;
    let count = 0;
    while (next !== null) {
      const page: RoundPage = await getJSON<RoundPage>(`/api/renders/${enc(id)}/rounds?since=${next}`);
      for (const r of page.rows) out.push(roundFromRow(r));
      count = page.count;
      next = page.next;
    }
    return { rounds: out, count };
  },
  map: (id: string, kind: "spp" | "error", size = 256) =>
    getJSON<PixelMap>(`/api/renders/${enc(id)}/maps?kind=${kind}&size=${size}`),
  buckets: (id: string) => getJSON<Buckets>(`/api/renders/${enc(id)}/buckets`),
  previewUrl: (id: string, exposure: number, version: number, size = 1024) =>
    `/api/renders/${enc(id)}/preview.png?exposure=${exposure}&size=${size}&v=${version}`,
  workers: () => getJSON<{ workers: Worker[]; now_ms: number }>("/api/workers"),
  scenes: () => getJSON<SceneList>("/api/scenes"),
  methods: () => getJSON<{ methods: MethodInfo[] }>("/api/methods"),
  studies: () => getJSON<{ studies: Study[] }>("/api/studies"),
  studyFileUrl: (s: Pick<Study, "source" | "name">, file: string) =>
    `/api/studies/${enc(s.source)}/${enc(s.name)}/${file.split("/").map(enc).join("/")}`,
};
