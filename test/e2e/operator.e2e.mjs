// Browser test of the operator page: headless Debian Chromium driven by playwright-core (from
// assets/node_modules) against a running Neptunus server with a simulated vehicle.
//
//   (cd assets && npm install && npm run build)
//   NEPTUNUS_URL=http://127.0.0.1:4102 node --test test/e2e/operator.e2e.mjs
//
// NEPTUNUS_URL defaults to http://127.0.0.1:4000, CHROMIUM_PATH to /usr/bin/chromium.
// Screenshots go to test/e2e/artifacts/ (git-ignored). Every wait has a timeout; the browser is
// closed in `after`, so the process exits whether the server is there or not.

import assert from "node:assert/strict";
import { existsSync, mkdirSync } from "node:fs";
import { createRequire } from "node:module";
import { dirname, join } from "node:path";
import { after, before, test } from "node:test";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const root = join(here, "..", "..");
const require = createRequire(join(root, "assets", "package.json"));

const BASE = (process.env.NEPTUNUS_URL || "http://127.0.0.1:4000").replace(/\/+$/, "");
const CHROMIUM = process.env.CHROMIUM_PATH || "/usr/bin/chromium";
const ARTIFACTS = join(here, "artifacts");
const CHROMIUM_ARGS = [
  "--no-sandbox",
  "--disable-gpu",
  "--disable-quic",
  "--no-first-run",
  "--disable-background-networking",
  "--disable-component-update",
  "--disable-sync",
];

const WAIT_MS = 5000;
const TEST_MS = 60000;

let chromium;
let browser;
/** Uncaught errors and console errors of every page, checked at the end of each test. */
const pageProblems = [];

function loadPlaywright() {
  try {
    return require("playwright-core").chromium;
  } catch (err) {
    throw new Error(
      `playwright-core not found in assets/node_modules (${err.message}): run \`npm install\` in assets/`,
    );
  }
}

async function get(path) {
  try {
    return await fetch(`${BASE}${path}`, { signal: AbortSignal.timeout(2000) });
  } catch (err) {
    throw new Error(
      `Neptunus server not reachable at ${BASE} (${err.cause?.message ?? err.message}). ` +
        "Start it (e.g. `NEPTUNUS_PORT=4102 mix run --no-halt`) and set NEPTUNUS_URL.",
    );
  }
}

before(async () => {
  chromium = loadPlaywright();
  assert.ok(existsSync(CHROMIUM), `no Chromium at ${CHROMIUM} (apt-get install chromium, or set CHROMIUM_PATH)`);
  const health = await get("/api/health");
  assert.equal(health.status, 200, `GET ${BASE}/api/health answered ${health.status}`);
  const js = await get("/assets/app.js");
  assert.equal(js.status, 200, `GET ${BASE}/assets/app.js answered ${js.status}: run \`npm run build\` in assets/`);
  mkdirSync(ARTIFACTS, { recursive: true });
  browser = await chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, timeout: 30000 });
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

/** A fresh context and page on the operator page. */
async function openOperator({ width, height, name, touch = false }) {
  const context = await browser.newContext({ viewport: { width, height }, hasTouch: touch });
  context.setDefaultTimeout(WAIT_MS);
  const page = await context.newPage();
  page.on("pageerror", (err) => pageProblems.push(`[${name}] uncaught: ${err.message}`));
  page.on("console", (msg) => {
    if (msg.type() === "error") pageProblems.push(`[${name}] console.error: ${msg.text()}`);
  });
  await page.goto(`${BASE}/?name=${encodeURIComponent(name)}`, { waitUntil: "load", timeout: WAIT_MS });
  await waitConnected(page);
  return { context, page };
}

async function waitConnected(page) {
  await page
    .locator('#status[data-state="connected"]')
    .waitFor({ timeout: WAIT_MS })
    .catch(async () => {
      const status = await page.locator("#status").textContent();
      const message = await page.locator("#message").textContent();
      throw new Error(`page never showed "connected" (status: "${status}", message: "${message}")`);
    });
  // telemetry on screen: heading is a number
  await page.waitForFunction(() => /^\d+\.\d$/.test(document.querySelector("#heading")?.textContent ?? ""), null, {
    timeout: WAIT_MS,
  });
}

async function num(page, selector) {
  const text = (await page.locator(selector).textContent()) ?? "";
  const value = Number.parseFloat(text);
  assert.ok(Number.isFinite(value), `${selector} shows "${text}", not a number`);
  return value;
}

async function readouts(page) {
  return {
    heading: await num(page, "#heading"),
    depth: await num(page, "#depth"),
    x: await num(page, "#x"),
    y: await num(page, "#y"),
  };
}

/** Waits until `read()` satisfies `pred`; returns the last value. */
async function until(read, pred, ms, what) {
  const deadline = Date.now() + ms;
  let last;
  for (;;) {
    last = await read();
    if (pred(last)) return last;
    if (Date.now() > deadline) assert.fail(`timed out after ${ms} ms waiting for ${what}; last: ${JSON.stringify(last)}`);
    await new Promise((r) => setTimeout(r, 100));
  }
}

const thrusterValues = async (page) => ({
  port: await num(page, "#thr-port"),
  vertical: await num(page, "#thr-vertical"),
  starboard: await num(page, "#thr-starboard"),
});
const allZero = (t) => t.port === 0 && t.vertical === 0 && t.starboard === 0;

async function hold(page, code, ms) {
  await page.keyboard.down(code);
  try {
    await page.waitForTimeout(ms);
  } finally {
    await page.keyboard.up(code);
  }
}

function assertNoPageProblems() {
  const problems = pageProblems.splice(0);
  assert.deepEqual(problems, [], `the page reported errors:\n${problems.join("\n")}`);
}

test("operator page: keyboard drives the simulated vehicle (desktop 1280×800)", { timeout: TEST_MS }, async () => {
  const { context, page } = await openOperator({ width: 1280, height: 800, name: "e2e-desktop" });
  try {
    assert.equal(await page.title().then((t) => t.startsWith("Neptunus")), true);
    assert.match((await page.locator("#vehicle-id").textContent()) ?? "", /\S/);
    await until(() => num(page, "#observers"), (n) => n >= 1, WAIT_MS, "observers ≥ 1");

    // Start from rest (the simulator may still coast from an earlier run).
    assert.ok(allZero(await thrusterValues(page)), "thrusters must be at zero before we press anything");
    const start = await readouts(page);
    assert.ok(start.heading >= 0 && start.heading < 360, `heading ${start.heading} outside 0..359.9`);

    // --- W: surge forward -------------------------------------------------------------------
    await page.keyboard.down("KeyW");
    try {
      await until(() => num(page, "#cmd-surge"), (v) => v > 0, WAIT_MS, "commanded surge > 0 while W is held");
      await until(async () => (await thrusterValues(page)).port, (v) => v !== 0, WAIT_MS, "port thruster running");
      await page.waitForTimeout(1000);
      await page.screenshot({ path: join(ARTIFACTS, "operator-desktop.png"), fullPage: true });
    } finally {
      await page.keyboard.up("KeyW");
    }
    assert.equal(
      ((await page.locator("#message").getAttribute("data-kind")) ?? "") === "error",
      false,
      `error shown while driving: ${await page.locator("#message").textContent()}`,
    );
    assert.equal(await page.locator("#pilot").textContent(), "e2e-desktop");
    await until(() => thrusterValues(page), allZero, WAIT_MS, "thrusters back to 0 after releasing W");
    await until(() => num(page, "#cmd-surge"), (v) => v === 0, WAIT_MS, "commanded surge back to 0");
    const moved = await until(
      () => readouts(page),
      (r) => Math.hypot(r.x - start.x, r.y - start.y) >= 0.02,
      WAIT_MS,
      `position to change from x=${start.x}, y=${start.y}`,
    );
    assert.notEqual(moved.x, start.x, "x did not change");

    // --- Q (or E if Q cannot move it, e.g. at the surface): heave -----------------------------
    const depth0 = await num(page, "#depth");
    await hold(page, "KeyQ", 1000);
    await until(() => thrusterValues(page), allZero, WAIT_MS, "thrusters back to 0 after releasing Q");
    let depth1 = await num(page, "#depth");
    if (Math.abs(depth1 - depth0) < 0.01) {
      await hold(page, "KeyE", 1000);
      await until(() => thrusterValues(page), allZero, WAIT_MS, "thrusters back to 0 after releasing E");
      depth1 = await until(
        () => num(page, "#depth"),
        (d) => Math.abs(d - depth0) >= 0.01,
        WAIT_MS,
        `depth to change from ${depth0} with Q or E`,
      );
    }
    assert.ok(Math.abs(depth1 - depth0) >= 0.01, `depth did not change (${depth0} → ${depth1})`);

    // --- a second operator (tablet 1024×768) is refused while the first pilots ---------------
    const tablet = await openOperator({ width: 1024, height: 768, name: "e2e-tablet", touch: true });
    try {
      await until(() => num(page, "#observers"), (n) => n >= 2, WAIT_MS, "observers ≥ 2 on the desktop page");
      assert.equal(await tablet.page.locator("#pilot").textContent(), "e2e-desktop");
      await tablet.page.keyboard.down("KeyW");
      await tablet.page.waitForTimeout(200);
      await tablet.page.keyboard.up("KeyW");
      await tablet.page
        .locator("#message", { hasText: "not_in_control" })
        .waitFor({ timeout: WAIT_MS });
      assert.ok(allZero(await thrusterValues(page)), "a refused operator moved the thrusters");
      // readable on a tablet: nothing wider than the viewport
      const overflow = await tablet.page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
      assert.ok(overflow <= 0, `page is ${overflow}px wider than the 1024px viewport`);
      await tablet.page.screenshot({ path: join(ARTIFACTS, "operator-tablet.png"), fullPage: true });
    } finally {
      await tablet.context.close();
    }
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

test("operator page: closing the pilot's page releases control; blur stops (1920×1080)", { timeout: TEST_MS }, async () => {
  // The previous test's pilot closed its page: a new page must be able to drive.
  const { context, page } = await openOperator({ width: 1920, height: 1080, name: "e2e-wide" });
  try {
    await until(async () => (await page.locator("#pilot").textContent()) ?? "", (p) => p !== "e2e-desktop", WAIT_MS, "pilot released");
    await page.keyboard.down("KeyD");
    try {
      await until(() => num(page, "#cmd-yaw"), (v) => v > 0, WAIT_MS, "commanded yaw > 0 while D is held");
      await page.screenshot({ path: join(ARTIFACTS, "operator-wide.png") });
      // Safety: the window losing focus stops the vehicle although D is still down.
      await page.evaluate(() => window.dispatchEvent(new Event("blur")));
      await until(() => thrusterValues(page), allZero, WAIT_MS, "thrusters at 0 after the window lost focus");
      await page.locator("#message", { hasText: "Stopped" }).waitFor({ timeout: WAIT_MS });
    } finally {
      await page.keyboard.up("KeyD");
    }
    await until(() => thrusterValues(page), allZero, WAIT_MS, "thrusters at 0 after releasing D");
    assert.equal(await page.locator("#pilot").textContent(), "e2e-wide");
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});
