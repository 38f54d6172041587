// A render's mean bias against its reference as the dashboard shows it: the signed
// fraction by which the image is too bright or too dark, with its standard error, as the
// command line's `aliquot compare` says it (coordinator/image/error_metric.h). E falls as
// a biased method converges; only this shows the image staying too dark.

/** Three standard errors: a bias beyond them is one the image's noise does not explain. */
export const NOISE_SE = 3;

/** Whether |bias| exceeds 3 SE; false when either is absent or not finite. */
export function biasBeyondNoise(bias: number | null | undefined, se: number | null | undefined): boolean {
  if (bias === null || bias === undefined || se === null || se === undefined) return false;
  if (!Number.isFinite(bias) || !Number.isFinite(se)) return false;
  return Math.abs(bias) > NOISE_SE * se;
}

// As printf's %+.3g / %.2g: significant digits without trailing zeros.
function digits(v: number, precision: number): string {
  return String(Number(v.toPrecision(precision)));
}

/** "-4.91 % ± 0.12 %, beyond 3 SE", "+0.1 % ± 0.2 %", "-4.91 %" without an SE, "–" without a bias. */
export function biasText(bias: number | null | undefined, se: number | null | undefined): string {
  if (bias === null || bias === undefined || !Number.isFinite(bias)) return "–";
  const value = `${bias >= 0 ? "+" : ""}${digits(100 * bias, 3)} %`;
  if (se === null || se === undefined || !Number.isFinite(se)) return value;
  return `${value} ± ${digits(100 * se, 2)} %${biasBeyondNoise(bias, se) ? ", beyond 3 SE" : ""}`;
}
