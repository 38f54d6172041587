// Screenshots compared with committed baselines (tests/web/baselines/NAME.png), made stable
// first: every text that moves from run to run (times, rates, host names, versions) is
// replaced by a fixed placeholder, images and charts (whose noise and time axis differ
// between runs) are masked, animations are off; then the two PNGs are compared pixel by
// pixel with a tolerance for anti-aliasing. A missing baseline is written
// (and said so); WEB_E2E_UPDATE_BASELINES=1 writes them all again after a deliberate change.
import fs from "node:fs";
import path from "node:path";
import { decodePng, encodePng } from "./png.mjs";

const BASELINES = path.join(path.dirname(new URL(import.meta.url).pathname), "baselines");

// A pixel differs when a channel moves by more than this (font hinting moves a few).
const CHANNEL_TOLERANCE = 48;
// And the screenshots differ when more than this share of pixels do.
const PIXEL_SHARE = 0.004;

/**
 * Freezes what moves, masks what is drawn, keeps only the first rows of lists whose length
 * depends on timing (`keep`: {selector of the list: rows}), and hides (`hide`) regions
 * that other parts of the project change (the submit form's method parameters, a render's
 * parameter line) or whose presence depends on the coordinator's release (its event log);
 * they are checked by the assertions instead. Saves OUT/NAME-stable.png.
 */
export async function stableShot(page, out, name, { freeze = [], mask = [], keep = {}, hide = [] } = {}) {
  await page.evaluate(({ selectors, keep, hide }) => {
    for (const sel of hide) for (const el of document.querySelectorAll(sel)) el.style.display = "none";
    for (const [sel, n] of Object.entries(keep))
      for (const list of document.querySelectorAll(sel)) while (list.children.length > n) list.lastElementChild.remove();
    for (const sel of selectors)
      for (const el of document.querySelectorAll(sel)) {
        // Fixed text of a fixed width: the table's columns do not move with it.
        el.textContent = "▒▒▒▒";
        el.removeAttribute("title");
      }
    document.activeElement?.blur?.();
  }, { selectors: freeze, keep, hide });
  const file = path.join(out, `${name}-stable.png`);
  await page.screenshot({
    path: file,
    fullPage: true,
    animations: "disabled",
    caret: "hide",
    mask: mask.map((m) => page.locator(m)),
    maskColor: "#ff00ff",
  });
  return file;
}

/**
 * Compares OUT/NAME-stable.png with its baseline (png.mjs, in Node: no second browser
 * page); writes OUT/NAME-diff.png where they differ. Throws on a difference.
 */
export async function compareWithBaseline(out, name, log) {
  const actual = path.join(out, `${name}-stable.png`);
  const baseline = path.join(BASELINES, `${name}.png`);
  if (process.env.WEB_E2E_UPDATE_BASELINES === "1" || !fs.existsSync(baseline)) {
    fs.mkdirSync(BASELINES, { recursive: true });
    fs.copyFileSync(actual, baseline);
    log(`  wrote baseline ${path.relative(process.cwd(), baseline)}: look at it, then commit it`);
    return;
  }
  const a = decodePng(fs.readFileSync(actual));
  const b = decodePng(fs.readFileSync(baseline));
  if (a.width !== b.width || a.height !== b.height)
    throw new Error(`${name}: screenshot is ${a.width}x${a.height} against the baseline's ${b.width}x${b.height}`);
  const diff = Buffer.alloc(a.data.length);
  let differing = 0;
  for (let i = 0; i < a.data.length; i += 4) {
    const d = Math.max(Math.abs(a.data[i] - b.data[i]), Math.abs(a.data[i + 1] - b.data[i + 1]), Math.abs(a.data[i + 2] - b.data[i + 2]));
    const off = d > CHANNEL_TOLERANCE;
    if (off) differing++;
    diff[i] = off ? 255 : a.data[i] / 3;
    diff[i + 1] = off ? 0 : a.data[i + 1] / 3;
    diff[i + 2] = off ? 0 : a.data[i + 2] / 3;
    diff[i + 3] = 255;
  }
  const total = a.width * a.height;
  const share = differing / total;
  log(`  ${name}: ${differing} of ${total} pixels differ from the baseline (${(share * 100).toFixed(3)} %)`);
  if (differing) fs.writeFileSync(path.join(out, `${name}-diff.png`), encodePng({ width: a.width, height: a.height, data: diff }));
  if (share > PIXEL_SHARE)
    throw new Error(`${name}: ${(share * 100).toFixed(2)} % of pixels differ from tests/web/baselines/${name}.png (see ${name}-diff.png)`);
}
