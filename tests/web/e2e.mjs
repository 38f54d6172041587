// The dashboard end to end: a real coordinator (gRPC + HTTP + SQLite) and a real worker on
// loopback, the built dashboard in headless Chromium (Debian's chromium, playwright-core).
// It submits a render from the page, watches it converge (progress, preview, heat maps,
// one chart point per round), cancels one, compares two, reads a study report, kills the
// worker and sees it turn lost, and saves a screenshot of every page. The farm runs with
// its tokens: the page signs in with DATA/client.token first, the worker uses DATA/worker.token.
//
// Usage: node e2e.mjs path/to/aliquot [output-dir]   (run.sh installs what it needs)
import { spawn } from "node:child_process";
import fs from "node:fs";
import http from "node:http";
import net from "node:net";
import os from "node:os";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { chromium } from "playwright-core";
import { compareWithBaseline, stableShot } from "./screenshots.mjs";

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, "../..");
const ALIQUOT = path.resolve(process.argv[2] ?? "build/bin/aliquot");
const OUT = path.resolve(process.argv[3] ?? path.join(path.dirname(path.dirname(ALIQUOT)), "web-e2e"));
const WEB = path.resolve(process.env.ALIQUOT_WEB ?? path.join(REPO, "web", "dist"));
const CHROMIUM = process.env.CHROMIUM ?? "/usr/bin/chromium";
const MAX_RESPONSE = 100 * 1024;

fs.rmSync(OUT, { recursive: true, force: true });
fs.mkdirSync(OUT, { recursive: true });
const TMP = fs.mkdtempSync(path.join(os.tmpdir(), "aliquot-web-e2e-"));
const DATA = path.join(TMP, "data");

const results = [];
const procs = [];
let context = null;

function log(...args) {
  console.log(...args);
}

async function check(name, fn) {
  const start = Date.now();
  try {
    await fn();
    results.push({ name, ok: true });
    log(`PASS ${name} (${((Date.now() - start) / 1000).toFixed(1)} s)`);
  } catch (e) {
    results.push({ name, ok: false });
    log(`FAIL ${name}: ${e?.message ?? e}`);
  }
}

function assert(cond, message) {
  if (!cond) throw new Error(message);
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function waitFor(fn, { timeout = 30000, every = 100, what = "condition" } = {}) {
  const end = Date.now() + timeout;
  let last;
  while (Date.now() < end) {
    try {
      last = await fn();
      if (last) return last;
    } catch (e) {
      last = e;
    }
    await sleep(every);
  }
  throw new Error(`timed out after ${timeout / 1000} s waiting for ${what} (last: ${last?.message ?? JSON.stringify(last)})`);
}

function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.once("error", reject);
    s.listen(0, "127.0.0.1", () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
  });
}

function start(name, args) {
  const logFile = fs.openSync(path.join(OUT, `${name}.log`), "w");
  const p = spawn(ALIQUOT, args, { stdio: ["ignore", logFile, logFile] });
  p.exited = new Promise((resolve) => p.on("exit", (code, signal) => resolve({ code, signal })));
  procs.push(p);
  return p;
}

async function cleanup() {
  if (context) await context.close().catch(() => {});
  for (const p of procs) if (p.exitCode === null && p.signalCode === null) p.kill("SIGKILL");
  fs.rmSync(TMP, { recursive: true, force: true });
}

const overall = setTimeout(async () => {
  log("FAIL the whole test: timed out after 420 s");
  results.push({ name: "finishes in time", ok: false });
  await finish();
}, 420000);

async function finish() {
  clearTimeout(overall);
  await cleanup();
  const passed = results.filter((r) => r.ok).length;
  const failed = results.length - passed;
  log(`screenshots and logs in ${OUT}`);
  log(`${passed} passed, ${failed} failed`);
  process.exit(failed ? 1 : 0);
}

// ---- the farm ----

const grpcPort = await freePort();
const httpPort = await freePort();
const BASE = `http://127.0.0.1:${httpPort}`;
// The session cookie is named with the port (docs/API.md, "Authentication").
const COOKIE = `aliquot_session_${httpPort}`;

// The coordinator writes its client token at its first start; read once it answers.
let clientToken = null;
const withToken = (headers = {}) => ({ ...headers, Authorization: `Bearer ${clientToken}` });

async function api(pathname, init = {}) {
  const res = await fetch(BASE + pathname, { ...init, headers: withToken(init.headers) });
  const body = await res.json();
  if (!res.ok) throw new Error(`${pathname}: ${res.status} ${body.error}`);
  return body;
}

const submitJSON = (spec) =>
  api("/api/renders", { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(spec) });

const coordinator = start("coordinator", [
  "coordinator",
  "--grpc", `127.0.0.1:${grpcPort}`,
  "--http", `127.0.0.1:${httpPort}`,
  "--data", DATA,
  "--web", WEB,
  "--studies", path.join(TMP, "more-studies"), // instead of the source tree's: starts empty
  "--lease-seconds", "5",
  "--lost-seconds", "2",
]);
let worker = null;

await check("coordinator serves the API and the built dashboard", async () => {
  assert(fs.existsSync(path.join(WEB, "index.html")), `no built dashboard in ${WEB} (run web/build.sh)`);
  await waitFor(async () => (await fetch(`${BASE}/healthz`)).ok, { timeout: 20000, what: "/healthz" });
  const index = await (await fetch(`${BASE}/`)).text();
  assert(index.includes("<title>Aliquot</title>"), "GET / is not the dashboard");
  clientToken = fs.readFileSync(path.join(DATA, "client.token"), "utf8").trim();
  assert(/^[0-9a-f]{64}$/.test(clientToken), "DATA/client.token is not a 64-digit hex token");
  const workerToken = path.join(DATA, "worker.token");
  worker = start("worker", [
    "worker",
    "--coordinator", `127.0.0.1:${grpcPort}`,
    "--token-file", workerToken,
    "--threads", "1",
    "--name", "e2e-worker",
  ]);
  await waitFor(async () => (await api("/api/workers")).workers.length === 1, { what: "the worker to register" });
});

// Issue 13: what another site's page could make a browser send is refused.
function rawRequest(method, pathname, headers, body = "") {
  return new Promise((resolve, reject) => {
    const req = http.request({ host: "127.0.0.1", port: httpPort, method, path: pathname, headers }, (res) => {
      let text = "";
      res.on("data", (d) => (text += d));
      res.on("end", () => resolve({ status: res.statusCode, body: text }));
    });
    req.on("error", reject);
    req.end(body);
  });
}

await check("cross-site requests are refused with a JSON error", async () => {
  const spec = JSON.stringify({ scene: "cornell-box", resolution: "8x8", strategy: { spp: 1 } });
  const cases = [
    ["text/plain", { "Content-Type": "text/plain" }, 415],
    ["a foreign Origin", { "Content-Type": "application/json", Origin: "http://evil.example" }, 403],
    ["a foreign Host", { "Content-Type": "application/json", Host: `evil.example:${httpPort}` }, 403],
  ];
  for (const [what, headers, status] of cases) {
    const res = await rawRequest("POST", "/api/renders", headers, spec);
    assert(res.status === status, `POST with ${what}: ${res.status} ${res.body}`);
    assert(typeof JSON.parse(res.body).error === "string", `POST with ${what}: no JSON error`);
  }
  const page = await rawRequest("GET", "/", { Host: `rebound.example:${httpPort}` });
  assert(page.status === 403, `GET / with a foreign Host: ${page.status}`);
  const probe = await rawRequest("GET", "/healthz", { Host: "10.0.0.7:8080" });
  assert(probe.status === 200, `/healthz with a pod IP as Host: ${probe.status}`);
  assert((await api("/api/renders")).renders.length === 0, "a refused request created a render");
});

// Issue 13: the API wants the client token; the worker's is the wrong role.
await check("the API refuses requests without the client token", async () => {
  const workerToken = fs.readFileSync(path.join(DATA, "worker.token"), "utf8").trim();
  for (const pathname of ["/api/renders", "/api/events", "/api/workers", "/api/session"]) {
    const none = await rawRequest("GET", pathname, {});
    assert(none.status === 401, `GET ${pathname} without a token: ${none.status}`);
    assert(typeof JSON.parse(none.body).error === "string", `GET ${pathname}: no JSON error`);
    const worker = await rawRequest("GET", pathname, { Authorization: `Bearer ${workerToken}` });
    assert(worker.status === 403, `GET ${pathname} with the worker token: ${worker.status}`);
  }
  const spec = JSON.stringify({ scene: "cornell-box", resolution: "8x8", strategy: { spp: 1 } });
  const post = await rawRequest("POST", "/api/renders", { "Content-Type": "application/json" }, spec);
  assert(post.status === 401, `POST without a token: ${post.status}`);
  assert((await api("/api/renders")).renders.length === 0, "a refused request created a render");
});

// ---- the browser ----

const userDataDir = fs.mkdtempSync(path.join(TMP, "chromium-"));
context = await chromium.launchPersistentContext(userDataDir, {
  executablePath: CHROMIUM,
  headless: true,
  args: [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
  ],
  viewport: { width: 1440, height: 1000 },
});
// Every fetch the page makes, timed by the page's own clock.
await context.addInitScript(() => {
  const original = window.fetch.bind(window);
  window.__fetches = [];
  window.fetch = (input, init) => {
    window.__fetches.push([String(input instanceof Request ? input.url : input), performance.now()]);
    return original(input, init);
  };
});
const page = context.pages()[0] ?? (await context.newPage());
page.setDefaultTimeout(30000);

const requests = []; // every request the page makes: [url, time]
const apiSizes = []; // [url, bytes] of every API response
const pageErrors = [];
page.on("request", (r) => requests.push({ url: r.url(), t: Date.now() }));
page.on("response", async (r) => {
  const url = r.url();
  if (!url.startsWith(`${BASE}/api/`) || url.includes("/api/events")) return;
  try {
    apiSizes.push({ url, bytes: (await r.body()).length });
  } catch {
    /* navigation discarded it */
  }
});
page.on("pageerror", (e) => {
  pageErrors.push(String(e));
  log(`  page error: ${e.stack ?? e}`);
});
page.on("console", (m) => {
  if (m.type() === "error" && !/Failed to load resource/.test(m.text())) pageErrors.push(m.text());
});

const shot = (name) => page.screenshot({ path: path.join(OUT, `${name}.png`), fullPage: true });

// A fingerprint of what a canvas or image shows, computed in the page.
const pixels = (selector) =>
  page.$eval(selector, (el) => {
    let canvas = el;
    if (el instanceof HTMLImageElement) {
      if (!el.complete || !el.naturalWidth) return null;
      canvas = document.createElement("canvas");
      canvas.width = el.naturalWidth;
      canvas.height = el.naturalHeight;
      canvas.getContext("2d").drawImage(el, 0, 0);
    }
    const d = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
    let hash = 0;
    let sum = 0;
    for (let i = 0; i < d.length; i++) {
      hash = (hash * 31 + d[i]) | 0;
      if (i % 4 !== 3) sum += d[i];
    }
    return { hash, mean: sum / ((d.length / 4) * 3), width: canvas.width };
  });

const attr = (selector, name) => page.$eval(selector, (el, n) => el.getAttribute(n), name).catch(() => null);

await check("without the cookie the page shows the sign-in view, not an error", async () => {
  await page.goto(`${BASE}/#/renders`);
  await page.waitForSelector("#sign-in-form");
  const where = await page.textContent("#sign-in-where");
  assert(where.includes("DATA/client.token"), `the view says "${where}"`);
  assert((await attr("#sign-in-token", "type")) === "password", "the token field is not a password field");
  assert(await page.isHidden("#sign-out"), "sign-out offered before signing in");
  assert(!(await page.$("#renders-table")), "the renders page showed without a session");
  await shot("sign-in");
});

await check("a wrong token or the worker's is refused with a message", async () => {
  await page.fill("#sign-in-token", "not-the-client-token-0123456789");
  await page.click("#sign-in-button");
  const wrong = await page.waitForSelector("#sign-in-message.error").then((e) => e.textContent());
  assert(/not the client token/.test(wrong), `message was "${wrong}"`);
  await page.fill("#sign-in-token", fs.readFileSync(path.join(DATA, "worker.token"), "utf8").trim());
  await page.click("#sign-in-button");
  await waitFor(async () => /worker token/.test(await page.textContent("#sign-in-message")), { what: "the worker-token message" });
  assert(!(await context.cookies(BASE)).some((c) => c.name.startsWith("aliquot_session")), "a refused sign-in set a cookie");
  await shot("sign-in-refused");
});

await check("signing in with the client token shows the dashboard", async () => {
  await page.fill("#sign-in-token", clientToken);
  await page.click("#sign-in-button");
  await page.waitForSelector("#renders-table");
  await page.waitForSelector('#live[data-status="live"]');
  assert(await page.isVisible("#sign-out"), "no sign-out control");
  const cookie = (await context.cookies(BASE)).find((c) => c.name === COOKIE);
  assert(cookie && cookie.httpOnly && cookie.sameSite === "Strict", `cookie ${JSON.stringify({ ...cookie, value: "..." })}`);
  assert(cookie.value !== clientToken && !cookie.value.includes(clientToken), "the cookie carries the client token");
  assert(!(await page.evaluate(() => document.cookie)).includes("aliquot_session"), "the page's scripts can read the cookie");
});

await check("dashboard loads with a live update stream", async () => {
  await page.goto(`${BASE}/#/renders`);
  await page.waitForSelector('#live[data-status="live"]');
  await page.waitForSelector("#submit-scene option[value='cornell-box']", { state: "attached" });
  await page.waitForSelector("#submit-method option[value='dammertz']", { state: "attached" });
});

await check("a bad submission shows the server's message", async () => {
  await page.fill("#submit-resolution", "0x0");
  await page.click("#submit-button");
  const text = await page.waitForSelector(".form-message.error").then((e) => e.textContent());
  assert(/resolution/.test(text), `message was "${text}"`);
  assert((await api("/api/renders")).renders.length === 0, "a render was created");
});

await check("the form shows only the chosen method's parameters, from /api/methods", async () => {
  const { methods } = await api("/api/methods");
  const keys = () => page.$$eval("#submit-form [data-param]", (els) => els.map((e) => e.dataset.param));
  for (const name of ["optimal", "cycles", "dammertz"]) {
    await page.selectOption("#submit-method", name);
    const want = methods.find((m) => m.name === name).parameters.map((p) => p.key);
    await waitFor(async () => JSON.stringify(await keys()) === JSON.stringify(want), { what: `${name}'s fields ${want}` });
  }
  const options = await page.$$eval("#submit-method option", (els) => els.map((e) => e.value));
  assert(!options.includes("oracle"), `the form offers ${options}`);
  // Defaults and bounds as declared: dammertz's error norm is a choice, optimal's radius bounded.
  assert((await page.$eval('select[data-param="error_norm"]', (e) => e.value)) === "seed", "error_norm's default");
  await page.selectOption("#submit-method", "optimal");
  assert((await page.$eval('input[data-param="sigma_radius"]', (e) => e.max)) === "64", "sigma_radius's bound");
  assert((await page.$eval('input[data-param="spp"]', (e) => e.value)) === "64", "spp's default");
});

let renderId = null;
await check("submit a render from the page", async () => {
  await page.selectOption("#submit-scene", "cornell-box");
  await page.fill("#submit-resolution", "128x128");
  await page.fill("#submit-seed", "5");
  await page.selectOption("#submit-method", "dammertz");
  await page.fill('input[data-param="max_spp"]', "1024");
  await page.click("#submit-button");
  const text = await page.waitForSelector(".form-message:not(.error)").then((e) => e.textContent());
  renderId = /submitted (r-\d+)/.exec(text)?.[1];
  assert(renderId, `message was "${text}"`);
  await page.waitForSelector(`tr[data-id="${renderId}"]`);
  const r = await api(`/api/renders/${renderId}`);
  assert(r.method === "dammertz" && r.width === 128 && r.seed === "5" && r.strategy.max_spp === 1024, `render is ${JSON.stringify(r)}`);
});

let early = null;
const seenPoints = new Set();
await check("the render page shows progress reaching 100 %", async () => {
  await page.click(`a[href="#/render/${renderId}"]`);
  await page.waitForSelector(".render-header[data-state]");
  // An early view, while the render is still running.
  await waitFor(async () => Number(await attr("#map-spp canvas", "data-samples")) > 0 && Number(await attr("#preview", "data-samples")) > 0, {
    what: "the first preview and maps",
  });
  early = {
    samples: Number(await attr("#map-spp canvas", "data-samples")),
    preview: await pixels("#preview"),
    spp: await pixels("#map-spp canvas"),
    error: await pixels("#map-error canvas"),
    state: await attr(".render-header", "data-state"),
  };
  await shot("render-running");
  await waitFor(
    async () => {
      seenPoints.add(Number(await attr("#chart-samples", "data-points")));
      return (await attr(".render-header", "data-state")) === "done";
    },
    { timeout: 180000, every: 200, what: "the render to finish" },
  );
  assert((await attr(".render-header", "data-progress")) === "1.0000", "progress is not 1");
  const label = await page.textContent("#render-progress .label");
  assert(label.includes("100 %"), `progress label "${label}"`);
  assert(early.state === "running", `the first view was already ${early.state}: the render was too quick to watch`);
});

await check("a render's page shows only its method's parameters", async () => {
  await waitFor(async () => /max spp 1024/.test((await page.textContent("p.params")) ?? ""), { what: "dammertz's parameters" });
  const text = await page.textContent("p.params");
  assert(/error norm seed/.test(text) && !/alpha|noise threshold|sigma radius/.test(text), `parameters: ${text}`);
  assert(!/[{}]/.test(await page.textContent("#render-outcome")), "raw outcome JSON");
});

let final = null;
await check("the preview and heat maps change as the render converges", async () => {
  final = await api(`/api/renders/${renderId}`);
  await waitFor(
    async () =>
      Number(await attr("#map-spp canvas", "data-samples")) === final.samples_done &&
      Number(await attr("#map-error canvas", "data-samples")) === final.samples_done &&
      Number(await attr("#preview", "data-samples")) === final.samples_done,
    { what: "images of the final samples" },
  );
  assert(early.samples < final.samples_done, `early view had ${early.samples} of ${final.samples_done} samples`);
  const now = { preview: await pixels("#preview"), spp: await pixels("#map-spp canvas"), error: await pixels("#map-error canvas") };
  for (const k of ["preview", "spp", "error"]) assert(now[k] && early[k] && now[k].hash !== early[k].hash, `${k} did not change`);
});

await check("the charts gain one point per round", async () => {
  const { rows, count } = await api(`/api/renders/${renderId}/rounds`);
  assert(count === final.rounds && count >= 5, `${count} rounds`);
  const plotted = rows.filter((r) => r[2] > 0 && r[4] > 0).length;
  await waitFor(async () => Number(await attr("#chart-samples", "data-points")) === plotted, { what: `${plotted} points` });
  assert(Number(await attr("#chart-time", "data-points")) === plotted, "error-vs-time chart differs");
  const tableRows = await page.$$eval("#rounds-table tbody tr", (r) => r.length);
  assert(tableRows === Math.min(200, count), `round table has ${tableRows} rows for ${count} rounds`);
  const grew = [...seenPoints].filter((n) => n > 0).sort((a, b) => a - b);
  assert(grew.length >= 3, `while running the chart showed only ${JSON.stringify(grew)} points`);
});

await check("bucket boundaries are drawn over the image", async () => {
  const { buckets } = await api(`/api/renders/${renderId}/buckets`);
  assert(buckets.length > 1, `${buckets.length} buckets`);
  assert(Number(await attr("#bucket-overlay", "data-buckets")) === buckets.length, "overlay bucket count differs");
  const overlay = await pixels("#bucket-overlay");
  assert(overlay.mean > 0, "the overlay is empty");
});

await check("the exposure slider brightens the preview", async () => {
  const before = await pixels("#preview");
  await page.fill("#exposure", "2");
  await waitFor(async () => (await attr("#preview", "src"))?.includes("exposure=2"), { what: "a new preview URL" });
  await waitFor(async () => (await pixels("#preview"))?.mean > before.mean * 1.3, { what: "a brighter preview" });
  await page.fill("#exposure", "0");
  await waitFor(async () => (await attr("#preview", "src"))?.includes("exposure=0"), { what: "exposure back to 0" });
  await sleep(300);
  await shot("render");
  await stableShot(page, OUT, "render", {
    freeze: [".stats dd", "#render-progress .label", "#render-events li", "#rounds-table td", "#render-outcome", "#round-note"],
    mask: ["#preview", "#bucket-overlay", ".heatmap", ".legend", ".chart"],
    keep: { "#rounds-table tbody": 3 },
    hide: ["p.params", "#render-events-note", ".events-card"],
  });
  await compareWithBaseline(OUT, "render", log);
});

await check("nothing is fetched faster than once a second while a render runs", async () => {
  // Still on the render page that watched the whole render.
  const fetches = await page.evaluate(() => window.__fetches);
  const kinds = { spp: /maps\?kind=spp/, error: /maps\?kind=error/, buckets: /\/buckets/, list: /\/api\/renders\?/, workers: /\/api\/workers/ };
  for (const [kind, re] of Object.entries(kinds)) {
    const times = fetches.filter(([url]) => re.test(url)).map(([, t]) => t);
    for (let i = 1; i < times.length; i++)
      assert(times[i] - times[i - 1] >= 990, `${kind} fetched ${Math.round(times[i] - times[i - 1])} ms after the previous one`);
  }
  const maps = fetches.filter(([url]) => kinds.spp.test(url)).length;
  assert(maps >= 3, `the spp map was fetched only ${maps} times while the render ran`);
  log(`  ${fetches.length} fetches while watching the render, ${maps} of the spp map`);
});

await check("a render's page: submission time, no raw outcome, EXR and PNG downloads", async () => {
  // The finished Dammertz render's page, unfrozen (the screenshot above froze its numbers).
  await page.reload();
  await page.waitForSelector('.render-header[data-state="done"]');
  assert(/\d/.test(await page.textContent('dd[data-stat="submitted"]')), "no submission time");
  assert((await page.textContent('dd[data-stat="eta"]')).trim() === "–", "a finished render has an ETA");
  const outcome = await page.textContent("#render-outcome");
  assert(!outcome.includes("{") && !outcome.includes('"'), `outcome shown as JSON: ${outcome}`);
  assert(await page.isHidden("#priority-controls"), "a finished render offers a priority change");
  const exr = await page.request.get(BASE + (await attr("#download-exr", "href")));
  assert(exr.status() === 200, `EXR download: ${exr.status()}`);
  const exrBytes = await exr.body();
  assert(exrBytes.readUInt32LE(0) === 20000630, "the EXR download is not an OpenEXR file");
  const png = await page.request.get(BASE + (await attr("#download-png", "href")));
  const pngBytes = await png.body();
  assert(png.status() === 200 && pngBytes.toString("latin1", 1, 4) === "PNG", `PNG download: ${png.status()}`);
  assert(pngBytes.readUInt32BE(16) === 128 && pngBytes.readUInt32BE(20) === 128, "the PNG is not the render's size");
});

await check("a render's events are listed, or the page says the coordinator keeps none", async () => {
  const res = await fetch(`${BASE}/api/renders/${renderId}/events`, { headers: withToken() });
  if (res.status === 404) {
    await waitFor(async () => /no event log/.test(await page.textContent("#render-events-note")), { what: "the no-log note" });
    log("  the coordinator serves no render events yet (404): the page says so");
    return;
  }
  assert(res.ok, `GET events: ${res.status}`);
  const body = await res.json();
  const count = (Array.isArray(body) ? body : body.events).length;
  assert(count >= 1, "no events for a finished render");
  await page.reload();
  await waitFor(async () => Number(await attr("#render-events", "data-count")) === count, { what: `${count} events listed` });
});

let resubmitted = null;
await check("resubmit with changes: the form holds the render's spec", async () => {
  await page.click("#resubmit");
  await page.waitForSelector('#submit-form[data-from]');
  const value = (sel) => page.$eval(sel, (e) => e.value);
  assert((await value("#submit-method")) === "dammertz", "method not prefilled");
  assert((await value("#submit-resolution")) === "128x128", "resolution not prefilled");
  assert((await value("#submit-seed")) === "5", "seed not prefilled");
  assert((await value('input[data-param="max_spp"]')) === "1024", "max_spp not prefilled");
  await page.fill("#submit-resolution", "64x64");
  await page.click("#submit-button");
  const text = await page.locator(".form-message:not(.error)", { hasText: /submitted r-/ }).textContent();
  resubmitted = /submitted (r-\d+)/.exec(text)?.[1];
  const r = await api(`/api/renders/${resubmitted}`);
  assert(r.method === "dammertz" && r.width === 64 && r.seed === "5" && r.strategy.max_spp === 1024, `resubmitted ${JSON.stringify(r)}`);
  await waitFor(async () => (await api(`/api/renders/${resubmitted}`)).state === "done", { timeout: 60000, what: "the resubmitted render" });
});

await check("delete asks first, then removes the render", async () => {
  await page.goto(`${BASE}/#/render/${resubmitted}`);
  await page.waitForSelector('.render-header[data-state="done"]');
  page.once("dialog", (d) => d.dismiss());
  await page.click("#delete-render");
  await sleep(300);
  assert((await api(`/api/renders/${resubmitted}`)).id === resubmitted, "deleted although the dialog was dismissed");
  page.once("dialog", (d) => d.accept());
  await page.click("#delete-render");
  await page.waitForSelector("#renders-table");
  const gone = await fetch(`${BASE}/api/renders/${resubmitted}`, { headers: withToken() });
  assert(gone.status === 404, `the deleted render answers ${gone.status}`);
  assert(!(await page.$(`tr[data-id="${resubmitted}"]`)), "the deleted render is still listed");
});

// Names (submit --name) and the queued state come from the API of issue 32; a coordinator
// without them yet is said so in the log, and what it has is still checked.
let hasNames = true;
async function submitNamed(spec, name) {
  if (hasNames) {
    try {
      return await submitJSON({ ...spec, name });
    } catch (e) {
      if (!/unknown field 'name'/.test(e.message)) throw e;
      hasNames = false;
      log("  the API takes no render names yet: submitted without");
    }
  }
  return submitJSON(spec);
}

let longId = null;
await check("queued → running → done with a priority change; ETA; cancel from the list", async () => {
  // One worker of one thread: the long render holds it, the next ones wait their turn.
  const long = await submitJSON({ scene: "cornell-box", resolution: "128x128", strategy: { method: "uniform", spp: 100000 } });
  longId = long.id;
  await waitFor(async () => (await api(`/api/renders/${long.id}`)).samples_done > 0, { what: "the long render to start" });
  const small = { scene: "cornell-box", resolution: "64x64", strategy: { method: "uniform", spp: 16 } };
  const b = await submitNamed(small, "e2e second");
  const c = await submitNamed(small, "e2e third");
  await page.goto(`${BASE}/#/renders`);
  await page.waitForSelector(`tr[data-id="${c.id}"]`);
  const queued = (await api(`/api/renders/${c.id}`)).state === "queued";
  if (queued) {
    const position = (await api(`/api/renders/${c.id}`)).queue_position;
    assert(position >= 1, `queue_position ${position}`);
    await waitFor(async () => (await page.textContent(`tr[data-id="${c.id}"] td[data-col="eta"]`)).trim() === `queued #${(await api(`/api/renders/${c.id}`)).queue_position}`, {
      what: "the queued render's place in the ETA column",
    });
    assert((await attr(`tr[data-id="${c.id}"]`, "data-state")) === "queued", "the row is not queued");
  } else log("  the API has no queued state yet: queued renders read running at 0 samples");
  if (hasNames) assert((await page.textContent(`tr[data-id="${b.id}"] a.render-link`)).trim() === "e2e second", "the name is not shown");
  await waitFor(async () => /\d/.test(await page.textContent(`tr[data-id="${long.id}"] td[data-col="eta"]`)), { what: "the running render's ETA" });

  // The second render jumps the queue: priority 10 from its page.
  await page.goto(`${BASE}/#/render/${b.id}`);
  await page.waitForSelector("#priority-input");
  assert(await page.isVisible("#priority-controls"), "no priority control on an unfinished render");
  assert(await page.isHidden("#delete-render"), "delete offered on an unfinished render");
  await page.fill("#priority-input", "10");
  await page.click("#priority-set");
  await waitFor(async () => (await api(`/api/renders/${b.id}`)).priority === 10, { what: "priority 10 in the API" });
  await page.waitForSelector('.render-header[data-state="done"]', { timeout: 60000 });
  assert((await api(`/api/renders/${long.id}`)).state === "running", "the long render finished before the prioritised one");
  if (queued) assert((await api(`/api/renders/${c.id}`)).state === "queued", "the third render left the queue before the long one");

  await page.goto(`${BASE}/#/renders`);
  await page.click(`button[data-cancel="${long.id}"]`);
  await page.waitForSelector(`tr[data-id="${long.id}"][data-state="cancelled"]`);
  assert((await api(`/api/renders/${long.id}`)).state === "cancelled", "the API does not say cancelled");
  await page.waitForSelector(`tr[data-id="${c.id}"][data-state="done"]`, { timeout: 60000 });
});

// Whatever failed above, the long render must not hold the only worker for what follows.
if (longId && (await api(`/api/renders/${longId}`)).state === "running")
  await api(`/api/renders/${longId}/cancel`, { method: "POST", headers: { "Content-Type": "application/json" }, body: "{}" });

let uniformId = null;
await check("compare two renders of one scene", async () => {
  const u = await submitJSON({ scene: "cornell-box", resolution: "128x128", seed: 5, strategy: { method: "uniform", spp: 128 } });
  uniformId = u.id;
  await waitFor(async () => (await api(`/api/renders/${uniformId}`)).state === "done", { timeout: 120000, what: "the uniform render" });
  const points = async (id) => (await api(`/api/renders/${id}/rounds`)).rows.filter((r) => r[2] > 0 && r[4] > 0).length;
  const want = (await points(renderId)) + (await points(uniformId));
  await page.goto(`${BASE}/#/compare?scene=cornell-box&ids=${renderId},${uniformId}`);
  await waitFor(async () => Number(await attr("#compare-time", "data-points")) === want, { what: `${want} points on the time chart` });
  assert(Number(await attr("#compare-budget", "data-points")) === want, "budget chart differs");
  const legend = await page.textContent("#compare-time");
  assert(legend.includes("dammertz") && legend.includes("uniform"), "legend lacks the methods");
  await sleep(300);
  await shot("compare");
});

let optimalId = null;
await check("charts: the pilot shown, axes scaled to the render, legends without --", async () => {
  const o = await submitJSON({ scene: "cornell-box", resolution: "128x128", seed: 2, strategy: { method: "optimal", spp: 64 } });
  optimalId = o.id;
  await page.goto(`${BASE}/#/render/${o.id}`);
  await page.waitForSelector(".render-header[data-state]");
  await waitFor(async () => (await api(`/api/renders/${o.id}`)).state === "done", { timeout: 60000, what: "the optimal render" });
  const r = await api(`/api/renders/${o.id}`);
  const rows = (await api(`/api/renders/${o.id}/rounds`)).rows;
  await waitFor(async () => Number(await attr("#chart-samples", "data-points")) === rows.length, { what: `${rows.length} points` });
  const pilot = Math.max(4, Math.floor(0.5 * 64)) * 128 * 128; // docs/STRATEGIES.md
  assert((await attr("#chart-samples", "data-pilot")).split(",")[1] === String(pilot), `pilot shaded as ${await attr("#chart-samples", "data-pilot")}`);
  assert((await attr("#chart-time", "data-pilot")) !== "", "no pilot on the time chart");
  assert((await attr("#chart-note", "data-pilot")) === "done", "the pilot is not counted done");
  const xMax = Number(await attr("#chart-samples", "data-x-max"));
  assert(xMax >= r.samples_done && xMax < 1.5 * r.samples_done, `samples axis ends at ${xMax} for ${r.samples_done} samples`);
  const tMax = Number(await attr("#chart-time", "data-x-max"));
  const lastT = rows.at(-1)[3];
  assert(tMax >= lastT && tMax < 1.5 * lastT, `time axis ends at ${tMax} s for a ${lastT} s render`);
  const legend = () => page.textContent("#chart-samples .u-legend");
  assert(!(await legend()).includes("--"), `legend without hover: ${await legend()}`);
  const box = await page.locator("#chart-samples .u-over").boundingBox();
  for (const f of [0.1, 0.5, 0.9]) {
    await page.mouse.move(box.x + box.width * f, box.y + box.height / 2);
    await sleep(100);
    assert(!(await legend()).includes("--"), `hover legend at ${f}: ${await legend()}`);
  }
  await page.mouse.move(0, 0);
  await shot("render-optimal");
});

// The issue's own example, too long to run here: an optimal render of 268 M samples in its
// pilot (half the budget, one long round) 35 s in, served by the browser's router.
await check("a render in its pilot: the charts show it, scaled to the render, not empty", async () => {
  const id = "r-999999";
  const now = Date.now();
  const render = {
    id, scene: "cornell-box", method: "optimal", state: "running", width: 1024, height: 1024, seed: "1",
    samples_done: 70e6, samples_planned: 268435456, rounds: 0, seconds: 35, samples_per_second: 2e6,
    error_estimate: null, error_vs_reference: null, created_ms: now - 36000, progress: 70e6 / 268435456,
    priority: 0, rays: 0, outcome: {}, strategy: { method: "optimal", spp: 256, budget: 0, min_spp: 4, floor_fraction: 0.5 },
  };
  const json = (route, status, body) => route.fulfill({ status, contentType: "application/json", body: JSON.stringify(body) });
  const handler = (route) => {
    const p = new URL(route.request().url()).pathname;
    if (p === `/api/renders/${id}`) return json(route, 200, render);
    if (p === `/api/renders/${id}/rounds`) return json(route, 200, { id, columns: [], rows: [], count: 0, since: 0, next: null });
    return json(route, 404, { error: "render 'r-999999' has no image yet" });
  };
  const matcher = (url) => url.pathname.startsWith(`/api/renders/${id}`);
  await page.route(matcher, handler);
  try {
    await page.goto(`${BASE}/#/render/${id}`);
    await page.waitForSelector('#chart-note[data-pilot="running"]');
    const note = await page.textContent("#chart-note");
    assert(/pilot: 70.0M of its 134.2M samples traced/.test(note), `note says "${note}"`);
    assert((await attr("#chart-samples", "data-pilot")).split(",")[1] === "134218000", `pilot shaded as ${await attr("#chart-samples", "data-pilot")}`);
    const xMax = Number(await attr("#chart-samples", "data-x-max"));
    assert(xMax > 268e6 && xMax < 400e6, `samples axis ends at ${xMax}, not near 268 M`);
    const tMax = Number(await attr("#chart-time", "data-x-max"));
    // 35 s done, (268 M - 70 M) / 2 M/s = 99 s left: about 134 s, not 16 minutes.
    assert(tMax > 134 && tMax < 200, `time axis ends at ${tMax} s`);
    assert((await page.textContent('dd[data-stat="eta"]')).includes("s"), "no ETA in the pilot");
    assert(!(await page.textContent("#chart-samples .u-legend")).includes("--"), "legend reads --");
    await shot("render-pilot");
  } finally {
    await page.unroute(matcher, handler);
  }
});

await check("the renders page lists every render with its thumbnail; sort and filter", async () => {
  await page.goto(`${BASE}/#/renders`);
  await page.waitForSelector(`tr[data-id="${uniformId}"][data-state="done"]`);
  const all = (await api("/api/renders")).renders;
  const rows = await page.$$eval("#renders-table tbody tr", (r) => r.length);
  assert(rows === all.length, `${rows} rows for ${all.length} renders`);
  const done = await page.textContent(`tr[data-id="${renderId}"] .progress-cell`);
  assert(done.includes("100 %"), `progress cell "${done}"`);
  assert(/\d/.test(await page.textContent(`tr[data-id="${renderId}"] td[data-col="submitted"]`)), "no submission time");
  await waitFor(
    () => page.$eval(`tr[data-id="${renderId}"] img.thumb`, (i) => i.complete && i.naturalWidth > 0 && i.naturalWidth <= 96),
    { what: "the thumbnail" },
  );
  const visibleIds = () => page.$$eval("#renders-table tbody tr:not([hidden])", (r) => r.map((x) => x.dataset.id));
  // Sort by name (an unnamed render by its id), then back.
  await page.click('th[data-sort="name"]');
  const byName = [...all].sort((a, b) => ((a.name || a.id).toLowerCase() < (b.name || b.id).toLowerCase() ? -1 : 1)).map((r) => r.id);
  assert(JSON.stringify(await visibleIds()) === JSON.stringify(byName), `sorted by name: ${await visibleIds()}`);
  assert(page.url().includes("sort=name"), `the address keeps no sort: ${page.url()}`);
  await page.click('th[data-sort="created"]');
  await page.selectOption("#filter-state", "done");
  const doneIds = all.filter((r) => r.state === "done").map((r) => r.id);
  assert((await visibleIds()).length === doneIds.length, `state filter shows ${await visibleIds()}`);
  assert(page.url().includes("state=done"), "the address keeps no filter");
  await page.selectOption("#filter-method", "dammertz");
  assert(JSON.stringify(await visibleIds()) === JSON.stringify([renderId]), `method filter shows ${await visibleIds()}`);
  await page.selectOption("#filter-state", "");
  await page.selectOption("#filter-method", "");
  await page.selectOption("#filter-scene", "cornell-box");
  assert((await visibleIds()).length === all.length, "scene filter hides cornell-box renders");
  await page.fill("#filter-text", hasNames ? "E2E THIRD" : uniformId);
  assert((await visibleIds()).length === 1, `text filter shows ${await visibleIds()}`);
  await page.reload(); // the view comes back from the address
  await page.waitForSelector("#renders-table tbody tr:not([hidden])");
  assert((await visibleIds()).length === 1, "the filter did not survive a reload");
  await page.goto(`${BASE}/#/renders`);
  await page.waitForSelector(`tr[data-id="${uniformId}"]`);
  await shot("renders");
  await stableShot(page, OUT, "renders", {
    freeze: ["#renders-table td.num", "#renders-table .progress .label", "#renders-table td.name-cell"],
    mask: ["img.thumb"],
    hide: ["#submit-form"],
  });
  await compareWithBaseline(OUT, "renders", log);
});

await check("studies: none yet, then a report with its table and chart", async () => {
  await page.goto(`${BASE}/#/studies`);
  await page.waitForSelector("#no-studies");
  await shot("studies-empty");
  const dir = path.join(DATA, "studies", "e2e-equal-budget");
  fs.mkdirSync(path.join(dir, "charts"), { recursive: true });
  const png = Buffer.from(await (await fetch(`${BASE}/api/renders/${renderId}/preview.png?exposure=0`, { headers: withToken() })).arrayBuffer());
  fs.writeFileSync(path.join(dir, "charts", "dammertz.png"), png);
  fs.writeFileSync(
    path.join(dir, "report.md"),
    [
      "# Equal budget (end-to-end fixture)",
      "",
      "Written by the **web end-to-end test**: a `report.md` like `aliquot study` writes.",
      "",
      "| method | samples | error estimate |",
      "|---|--:|--:|",
      `| dammertz | ${final.samples_done} | ${final.error_estimate.toFixed(5)} |`,
      "",
      "![dammertz preview](charts/dammertz.png)",
      "",
    ].join("\n"),
  );
  await page.reload();
  await page.click("#study-list a");
  await page.waitForSelector("#study-report h1");
  assert((await page.textContent("#study-report h1")).includes("Equal budget"), "no heading");
  const cells = await page.$$eval("#study-report td", (t) => t.map((c) => c.textContent));
  assert(cells.includes("dammertz"), `table cells ${JSON.stringify(cells)}`);
  await waitFor(() => page.$eval("#study-report img", (i) => i.complete && i.naturalWidth === 128), { what: "the report's image" });
  await shot("study");
});

await check("a killed worker turns lost on the workers page", async () => {
  await page.goto(`${BASE}/#/workers`);
  await page.waitForSelector('tr[data-name="e2e-worker"][data-state="idle"], tr[data-name="e2e-worker"][data-state="busy"]');
  const cell = (c) => page.textContent(`tr[data-name="e2e-worker"] td.${c}`).then((t) => t.trim());
  assert((await cell("host")) === os.hostname().slice(0, 128), `host ${await cell("host")}`);
  assert(/^\d+\.\d+\.\d+/.test(await cell("version")), `version ${await cell("version")}`);
  assert((await cell("failures")) === "0", `failures ${await cell("failures")}`);
  await shot("workers");
  await stableShot(page, OUT, "workers", {
    freeze: ["#workers-table td.num", "#workers-table td.host", "#workers-table td.version", "#workers-table td.lease", "#workers-table td.state"],
  });
  await compareWithBaseline(OUT, "workers", log);
  worker.kill("SIGKILL");
  await page.waitForSelector('tr[data-name="e2e-worker"][data-state="lost"]', { timeout: 15000 });
  assert((await page.textContent('tr[data-name="e2e-worker"] .state')).trim() === "lost", "badge does not say lost");
  await shot("workers-lost");
});

// The live stream faked by the browser's router: what the page does with a storage
// warning, and with a server that refuses streams (503 when too many are open).
const eventsUrl = `${BASE}/api/events`;
const countEvents = (since) => requests.filter((r) => r.url === eventsUrl && r.t >= since).length;

await check("a storage warning shows a banner on every page until it clears", async () => {
  assert(await page.isHidden("#storage-warning"), "banner shown without a warning");
  const warning = "cannot record round 3 of r-000001: database or disk is full";
  await page.route(eventsUrl, (route) =>
    route.fulfill({
      status: 200,
      headers: { "Content-Type": "text/event-stream", "Cache-Control": "no-store" },
      body: `retry: 60000\n\ndata: ${JSON.stringify({ type: "hello", now_ms: Date.now(), storage_warning: warning })}\n\n`,
    }),
  );
  await page.goto(`${BASE}/#/workers`);
  await page.reload();
  await page.waitForSelector("#storage-warning", { state: "visible" });
  const text = await page.textContent("#storage-warning");
  assert(text.includes("cannot write its record") && text.includes("database or disk is full"), `banner says "${text}"`);
  await page.goto(`${BASE}/#/renders`);
  assert(await page.isVisible("#storage-warning"), "banner gone on the renders page");
  await shot("storage-warning");
  await page.unroute(eventsUrl);
  await page.reload();
  await page.waitForSelector('#live[data-status="live"]');
  await page.waitForSelector("#storage-warning", { state: "hidden" });
});

await check("a refused live stream is retried with backoff, then goes live", async () => {
  await page.route(eventsUrl, (route) =>
    route.fulfill({
      status: 503,
      headers: { "Content-Type": "application/json", "Retry-After": "10" },
      body: JSON.stringify({ error: "too many live-update streams are open (at most 16); try again later" }),
    }),
  );
  const since = Date.now();
  await page.reload();
  await page.waitForSelector('#live[data-status="reconnecting"]');
  await sleep(5000);
  // 2 s, then 4 s later at the earliest: two or three attempts in 5 s, not one a second.
  const attempts = countEvents(since);
  assert(attempts >= 2 && attempts <= 3, `${attempts} attempts in 5 s`);
  await page.unroute(eventsUrl);
  await page.waitForSelector('#live[data-status="live"]', { timeout: 20000 });
  // What the browser logs about the refused streams is expected here.
  for (let i = pageErrors.length - 1; i >= 0; i--)
    if (/EventSource|503|Service Unavailable/.test(pageErrors[i])) pageErrors.splice(i, 1);
});

await check("sign out returns to the sign-in view, and a stale cookie does too", async () => {
  await page.goto(`${BASE}/#/workers`);
  await page.waitForSelector("#workers-table");
  await page.click("#sign-out");
  await page.waitForSelector("#sign-in-form");
  assert(!(await context.cookies(BASE)).some((c) => c.name === COOKIE), "the cookie is still there");
  await page.reload();
  await page.waitForSelector("#sign-in-form");
  // What a browser holds after the coordinator restarted (its sessions are in memory), or
  // after signing out elsewhere: a session id the server no longer knows.
  await context.addCookies([{ name: COOKIE, value: "0".repeat(64), url: BASE }]);
  await page.reload();
  await page.waitForSelector("#sign-in-form");
  await page.fill("#sign-in-token", clientToken);
  await page.click("#sign-in-button");
  await page.waitForSelector("#workers-table"); // back where the address says
});

await check("API responses stay under 100 KB", async () => {
  assert(apiSizes.length > 20, `only ${apiSizes.length} responses seen`);
  const big = apiSizes.filter((s) => s.bytes >= MAX_RESPONSE);
  assert(!big.length, `too large: ${big.map((b) => `${b.url} ${b.bytes}`).join(", ")}`);
  log(`  largest of ${apiSizes.length} API responses: ${Math.max(...apiSizes.map((s) => s.bytes))} bytes`);
});

await check("the page works offline: every request stays on the coordinator", async () => {
  const foreign = requests.filter((r) => !r.url.startsWith(BASE) && !r.url.startsWith("data:"));
  assert(!foreign.length, `requests elsewhere: ${foreign.map((r) => r.url).join(", ")}`);
  assert(!pageErrors.length, `page errors: ${pageErrors.join(" | ")}`);
});

await check("the coordinator stops on SIGTERM with the dashboard connected", async () => {
  coordinator.kill("SIGTERM");
  const exit = await Promise.race([coordinator.exited, sleep(15000).then(() => null)]);
  assert(exit, "still running 15 s after SIGTERM");
  assert(exit.code === 0, `exit ${JSON.stringify(exit)}`);
});

await finish();
