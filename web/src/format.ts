// Number formatting for tables and legends: counts with SI suffixes, errors with three
// significant digits, durations and "how long ago".

export function count(n: number): string {
  if (!Number.isFinite(n)) return "–";
  const a = Math.abs(n);
  if (a >= 1e9) return (n / 1e9).toFixed(a >= 1e10 ? 1 : 2) + "G";
  if (a >= 1e6) return (n / 1e6).toFixed(a >= 1e7 ? 1 : 2) + "M";
  if (a >= 1e4) return (n / 1e3).toFixed(a >= 1e5 ? 0 : 1) + "k";
  return String(Math.round(n));
}

export function error(v: number | null | undefined): string {
  if (v === null || v === undefined || !Number.isFinite(v)) return "–";
  if (v === 0) return "0";
  if (Math.abs(v) < 1e-3 || Math.abs(v) >= 1e4) return v.toExponential(2);
  return v.toPrecision(3);
}

export function seconds(s: number): string {
  if (!Number.isFinite(s) || s < 0) return "–";
  if (s < 10) return s.toFixed(2) + " s";
  if (s < 120) return s.toFixed(1) + " s";
  const m = Math.floor(s / 60);
  if (m < 120) return `${m} min ${Math.round(s - m * 60)} s`;
  return `${Math.floor(m / 60)} h ${m % 60} min`;
}

export function ago(thenMs: number, nowMs: number): string {
  if (!thenMs) return "never";
  const s = Math.max(0, (nowMs - thenMs) / 1000);
  if (s < 1) return "just now";
  if (s < 60) return `${Math.floor(s)} s ago`;
  if (s < 3600) return `${Math.floor(s / 60)} min ago`;
  return `${Math.floor(s / 3600)} h ago`;
}

export function percent(f: number): string {
  if (!Number.isFinite(f)) return "–";
  return `${Math.floor(Math.min(1, Math.max(0, f)) * 100)} %`;
}
