// Screenshots compared with committed baselines (tests/web/baselines/NAME.png), made stable
// first: every text that moves from run to run (times, rates, host names, versions) is
// replaced by a fixed placeholder, images and charts (whose noise and time axis differ
// between runs) are masked, animations are off; then the two PNGs are compared pixel by
// pixel in the browser with a tolerance for anti-aliasing. A missing baseline is written
// (and said so); WEB_E2E_UPDATE_BASELINES=1 writes them all again after a deliberate change.
import fs from "node:fs";
import path from "node:path";

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
 * Compares OUT/NAME-stable.png with its baseline in a page of the browser (no image
 * library needed); writes OUT/NAME-diff.png where they differ. Throws on a difference.
 */
export async function compareWithBaseline(page, out, name, log) {
  const actual = path.join(out, `${name}-stable.png`);
  const baseline = path.join(BASELINES, `${name}.png`);
  if (process.env.WEB_E2E_UPDATE_BASELINES === "1" || !fs.existsSync(baseline)) {
    fs.mkdirSync(BASELINES, { recursive: true });
    fs.copyFileSync(actual, baseline);
    log(`  wrote baseline ${path.relative(process.cwd(), baseline)}: look at it, then commit it`);
    return;
  }
  // A page of its own: the tested page keeps its state. Brought back to the front after,
  // or Chromium treats the tested page as hidden and stops its animation frames (and
  // with them Playwright's waiting for selectors).
  const tested = page;
  page = await tested.context().newPage();
  try {
    const url = (f) => `data:image/png;base64,${fs.readFileSync(f).toString("base64")}`;
    const result = await page.evaluate(
      async ({ a, b, tolerance }) => {
        const load = (src) =>
          new Promise((resolve, reject) => {
            const img = new Image();
            img.onload = () => resolve(img);
            img.onerror = () => reject(new Error("cannot decode a screenshot"));
            img.src = src;
          });
        const [ia, ib] = await Promise.all([load(a), load(b)]);
        if (ia.width !== ib.width || ia.height !== ib.height)
          return { size: `${ia.width}x${ia.height} against the baseline's ${ib.width}x${ib.height}` };
        const pixelsOf = (img) => {
          const c = document.createElement("canvas");
          c.width = img.width;
          c.height = img.height;
          const ctx = c.getContext("2d");
          ctx.drawImage(img, 0, 0);
          return ctx.getImageData(0, 0, c.width, c.height);
        };
        const da = pixelsOf(ia);
        const db = pixelsOf(ib).data;
        const diff = new ImageData(ia.width, ia.height);
        let differing = 0;
        for (let i = 0; i < db.length; i += 4) {
          const d = Math.max(Math.abs(da.data[i] - db[i]), Math.abs(da.data[i + 1] - db[i + 1]), Math.abs(da.data[i + 2] - db[i + 2]));
          const off = d > tolerance;
          if (off) differing++;
          diff.data[i] = off ? 255 : da.data[i] / 3;
          diff.data[i + 1] = off ? 0 : da.data[i + 1] / 3;
          diff.data[i + 2] = off ? 0 : da.data[i + 2] / 3;
          diff.data[i + 3] = 255;
        }
        const c = document.createElement("canvas");
        c.width = ia.width;
        c.height = ia.height;
        c.getContext("2d").putImageData(diff, 0, 0);
        return { differing, total: db.length / 4, diff: differing ? c.toDataURL("image/png") : null };
      },
      { a: url(actual), b: url(baseline), tolerance: CHANNEL_TOLERANCE },
    );
    if (result.size) throw new Error(`${name}: screenshot is ${result.size}`);
    const share = result.differing / result.total;
    log(`  ${name}: ${result.differing} of ${result.total} pixels differ from the baseline (${(share * 100).toFixed(3)} %)`);
    if (result.diff) fs.writeFileSync(path.join(out, `${name}-diff.png`), Buffer.from(result.diff.split(",")[1], "base64"));
    if (share > PIXEL_SHARE)
      throw new Error(`${name}: ${(share * 100).toFixed(2)} % of pixels differ from tests/web/baselines/${name}.png (see ${name}-diff.png)`);
  } finally {
    await page.close();
    await tested.bringToFront();
  }
}
