// Shared helpers of the browser tests (operator.e2e.mjs, developer.e2e.mjs): headless Debian
// Chromium driven by playwright-core (from assets/node_modules) against a running Neptunus
// server in local mode. NEPTUNUS_URL defaults to http://127.0.0.1:4000, CHROMIUM_PATH to
// /usr/bin/chromium. Screenshots go to test/e2e/artifacts/ (git-ignored).

import assert from "node:assert/strict";
import { existsSync, mkdirSync } from "node:fs";
import { createRequire } from "node:module";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const root = join(here, "..", "..");
const require = createRequire(join(root, "assets", "package.json"));

export const BASE = (process.env.NEPTUNUS_URL || "http://127.0.0.1:4000").replace(/\/+$/, "");
export const CHROMIUM = process.env.CHROMIUM_PATH || "/usr/bin/chromium";
export const ARTIFACTS = join(here, "artifacts");
// How long a test waits for what must happen (an element, a state, a reply) before it calls
// it a failure: generous, since the machine may be busy; every wait ends as soon as the thing
// happens. Nothing here measures speed.
export const WAIT_MS = 15000;
export const TEST_MS = 120000;
export const DESKTOP = { width: 1920, height: 1080 };
export const TABLET = { width: 1024, height: 768 };

const CHROMIUM_ARGS = [
  "--no-sandbox",
  "--disable-gpu",
  "--disable-quic",
  "--no-first-run",
  "--disable-background-networking",
  "--disable-component-update",
  "--disable-sync",
];

/** Uncaught errors and console errors of every page (Content-Security-Policy violations too). */
export const pageProblems = [];

/**
 * Makes every page of `context` report Content-Security-Policy violations as console errors
 * (which land in `pageProblems`): the server's policy must never block what the pages do.
 */
export async function reportCspViolations(context) {
  await context.addInitScript(() => {
    document.addEventListener("securitypolicyviolation", (e) => {
      console.error(`CSP violation: ${e.violatedDirective} blocked ${e.blockedURI || "inline"} (${e.sourceFile}:${e.lineNumber})`);
    });
  });
}

/**
 * Keeps every text `#message` shows on the pages of `context`, in order (`window.__messages`):
 * a later message replaces the one shown (on a busy machine a deadman stop of the next pilot
 * may come within the same second), so a check that a message was shown reads this.
 */
export async function recordMessages(context) {
  await context.addInitScript(() => {
    const seen = [];
    window.__messages = seen;
    const look = () => {
      const text = document.querySelector("#message")?.textContent ?? "";
      if (text !== "" && seen[seen.length - 1] !== text) seen.push(text);
    };
    new MutationObserver(look).observe(document, { childList: true, subtree: true, characterData: true });
  });
}

/** How many messages `page` has shown so far: `messageShown` after them waits for a newer one. */
export const messageCount = (page) => page.evaluate(() => window.__messages.length);

/** Waits until `page` has shown, after its first `since` messages, one containing `text`. */
export async function messageShown(page, text, since = 0) {
  await page.waitForFunction(([t, n]) => window.__messages.slice(n).some((m) => m.includes(t)), [text, since], {
    timeout: WAIT_MS,
  });
}

/** The page response carries the anti-framing headers (see NeptunusWeb.Endpoint.Guard). */
export function assertPageHeaders(response, where) {
  assert.ok(response, `${where}: no response`);
  const headers = response.headers();
  assert.match(headers["content-security-policy"] ?? "", /frame-ancestors 'none'/, `${where}: Content-Security-Policy`);
  assert.equal(headers["x-frame-options"], "DENY", `${where}: X-Frame-Options`);
}

async function get(path) {
  try {
    return await fetch(`${BASE}${path}`, { signal: AbortSignal.timeout(WAIT_MS) });
  } catch (err) {
    throw new Error(
      `Neptunus server not reachable at ${BASE} (${err.cause?.message ?? err.message}). ` +
        "Start it (e.g. `NEPTUNUS_PORT=4102 mix run --no-halt`) and set NEPTUNUS_URL.",
    );
  }
}

/** Checks the server and the built assets, launches Chromium. */
export async function launch() {
  let chromium;
  try {
    chromium = require("playwright-core").chromium;
  } catch (err) {
    throw new Error(`playwright-core not found in assets/node_modules (${err.message}): run \`npm install\` in assets/`);
  }
  assert.ok(existsSync(CHROMIUM), `no Chromium at ${CHROMIUM} (apt-get install chromium, or set CHROMIUM_PATH)`);
  const health = await get("/api/health");
  assert.equal(health.status, 200, `GET ${BASE}/api/health answered ${health.status}`);
  for (const asset of ["/assets/app.js", "/assets/dev.js", "/dev.html"]) {
    const res = await get(asset);
    assert.equal(res.status, 200, `GET ${BASE}${asset} answered ${res.status}: run \`npm run build\` in assets/`);
  }
  mkdirSync(ARTIFACTS, { recursive: true });
  return chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, timeout: 30000 });
}

/**
 * A fresh context and page at `path` (default the operator page as `name`), once `ready` (a
 * selector; default: connected to the server) shows; `wait`: its timeouts (ms).
 */
export async function open(browser, { width, height, name, touch = false, path = null, init = null, wait = WAIT_MS, ready = '#status[data-state="connected"]' }) {
  const context = await browser.newContext({ viewport: { width, height }, hasTouch: touch, isMobile: false });
  context.setDefaultTimeout(wait);
  await reportCspViolations(context);
  await recordMessages(context);
  const page = await context.newPage();
  if (init) await page.addInitScript(init);
  page.on("pageerror", (err) => pageProblems.push(`[${name}] uncaught: ${err.message}`));
  page.on("console", (msg) => {
    if (msg.type() === "error") pageProblems.push(`[${name}] console.error: ${msg.text()}`);
  });
  const response = await page.goto(`${BASE}${path ?? `/?name=${encodeURIComponent(name)}`}`, { waitUntil: "load", timeout: wait });
  assertPageHeaders(response, name);
  await page
    .locator(ready)
    .waitFor({ timeout: wait })
    .catch(async () => {
      const status = await page.locator("#status").textContent();
      throw new Error(`[${name}] page never showed "connected" (status: "${status}")`);
    });
  return { context, page };
}

/** Waits for telemetry on the operator page (heading is a number). */
export async function waitTelemetry(page) {
  await page.waitForFunction(() => /^\d+\.\d$/.test(document.querySelector("#heading")?.textContent ?? ""), null, {
    timeout: WAIT_MS,
  });
}

export async function num(page, selector) {
  const text = (await page.locator(selector).textContent()) ?? "";
  const value = Number.parseFloat(text);
  assert.ok(Number.isFinite(value), `${selector} shows "${text}", not a number`);
  return value;
}

/** Waits until `read()` satisfies `pred`; returns the last value. */
export async function until(read, pred, ms, what) {
  const deadline = Date.now() + ms;
  let last;
  for (;;) {
    last = await read();
    if (pred(last)) return last;
    if (Date.now() > deadline) assert.fail(`timed out after ${ms} ms waiting for ${what}; last: ${JSON.stringify(last)}`);
    await new Promise((r) => setTimeout(r, 50));
  }
}

export const thrusterValues = async (page) => ({
  port: await num(page, "#thr-port"),
  vertical: await num(page, "#thr-vertical"),
  starboard: await num(page, "#thr-starboard"),
});
export const allZero = (t) => t.port === 0 && t.vertical === 0 && t.starboard === 0;

export async function helmState(page) {
  const el = page.locator("#helm-state");
  return {
    text: (await el.textContent()) ?? "",
    state: await el.getAttribute("data-state"),
    me: await el.getAttribute("data-me"),
  };
}

/** Waits for a free helm, clicks "Request control": granted at once. */
export async function takeHelm(page) {
  await until(() => helmState(page), (h) => h.state === "free", WAIT_MS, "a free helm");
  await page.locator("#request-control:enabled").click();
  await page.locator('#helm-state[data-me="pilot"]').waitFor({ timeout: WAIT_MS });
}

export function assertNoPageProblems() {
  const problems = pageProblems.splice(0);
  assert.deepEqual(problems, [], `the pages reported errors:\n${problems.join("\n")}`);
}

export async function screenshot(page, name, { fullPage = true } = {}) {
  await page.screenshot({ path: join(ARTIFACTS, name), fullPage });
}

/**
 * A stubbed standard pad, an init script for `open`: `window.__pad` holds its axes and its 18
 * buttons (the standard 17 and the PlayStation pads' touchpad); the page reads copies.
 */
export const stubPad = () => {
  const buttons = () => Array.from({ length: 18 }, () => ({ value: 0, pressed: false, touched: false }));
  window.__pad = { axes: [0, 0, 0, 0], buttons: buttons() };
  Object.defineProperty(Navigator.prototype, "getGamepads", {
    configurable: true,
    value: () => [
      {
        id: "Stub pad (STANDARD GAMEPAD)",
        index: 0,
        connected: true,
        mapping: "standard",
        timestamp: performance.now(),
        axes: window.__pad.axes.slice(),
        buttons: window.__pad.buttons.map((b) => ({ ...b })),
      },
    ],
  });
};

const setButton = (page, index, pressed) =>
  page.evaluate(([i, p]) => (window.__pad.buttons[i] = { value: p ? 1 : 0, pressed: p, touched: p }), [index, pressed]);

/** Resolves after `n` animation frames of the page (its gamepad poller runs on them). */
export const afterFrames = (page, n = 2) =>
  page.evaluate(
    (count) =>
      new Promise((resolve) => {
        const step = (left) => (left === 0 ? resolve(undefined) : requestAnimationFrame(() => step(left - 1)));
        step(count);
      }),
    n,
  );

/**
 * Presses `index` for `ms`, then lets go. The page reads the pad on animation frames: the press
 * lasts two of them at least, and so does the release (a busy machine may give the page none
 * within `ms`).
 */
export async function pressButton(page, index, ms = 120) {
  await setButton(page, index, true);
  try {
    await page.waitForTimeout(ms);
    await afterFrames(page);
  } finally {
    await setButton(page, index, false);
  }
  await afterFrames(page);
}
