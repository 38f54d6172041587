// Colour maps for the heat maps: perceptually ordered ramps given by a few stops and
// interpolated linearly into a 256-entry table.

type RGB = [number, number, number];

function ramp(stops: RGB[]): Uint8ClampedArray {
  const table = new Uint8ClampedArray(256 * 3);
  for (let i = 0; i < 256; i++) {
    const t = (i / 255) * (stops.length - 1);
    const k = Math.min(stops.length - 2, Math.floor(t));
    const f = t - k;
    for (let c = 0; c < 3; c++) table[i * 3 + c] = stops[k][c] + (stops[k + 1][c] - stops[k][c]) * f;
  }
  return table;
}

// Dark blue through teal and green to yellow: sample counts.
export const SPP_MAP = ramp([
  [30, 20, 80],
  [40, 70, 140],
  [30, 130, 140],
  [60, 180, 100],
  [180, 215, 50],
  [250, 235, 40],
]);

// Black through purple and orange to pale yellow: error.
export const ERROR_MAP = ramp([
  [5, 5, 20],
  [70, 15, 110],
  [160, 40, 100],
  [230, 90, 50],
  [250, 180, 40],
  [252, 250, 170],
]);

export function decodeBase64(data: string): Uint8Array {
  const bin = atob(data);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

/** RGBA pixels of a quantised map through `table`. */
export function colorize(bytes: Uint8Array, table: Uint8ClampedArray): Uint8ClampedArray<ArrayBuffer> {
  const out = new Uint8ClampedArray(new ArrayBuffer(bytes.length * 4));
  for (let i = 0; i < bytes.length; i++) {
    const v = bytes[i] * 3;
    out[i * 4] = table[v];
    out[i * 4 + 1] = table[v + 1];
    out[i * 4 + 2] = table[v + 2];
    out[i * 4 + 3] = 255;
  }
  return out;
}

export function cssColor(table: Uint8ClampedArray, t: number): string {
  const i = Math.round(Math.min(1, Math.max(0, t)) * 255) * 3;
  return `rgb(${table[i]}, ${table[i + 1]}, ${table[i + 2]})`;
}
