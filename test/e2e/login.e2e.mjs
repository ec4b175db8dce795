// Browser test of login, roles and the main station's takeover: headless Debian Chromium
// driven by playwright-core against a Neptunus server in *secure mode*. ExUnit
// (test/e2e/external_test.exs) switches the test server to secure mode with these users and
// passes their passwords in NEPTUNUS_E2E_LOGINS (JSON {name: password}):
//
//   e2e-pilot (pilot), e2e-main (main_station), e2e-olga (observer)
//
// NEPTUNUS_URL defaults to http://127.0.0.1:4000, CHROMIUM_PATH to /usr/bin/chromium.
// Screenshots go to test/e2e/artifacts/.

import assert from "node:assert/strict";
import { existsSync, mkdirSync } from "node:fs";
import { createRequire } from "node:module";
import { dirname, join } from "node:path";
import { after, before, test } from "node:test";
import { fileURLToPath } from "node:url";
import { messageCount, messageShown, recordMessages } from "./helpers.mjs";

const here = dirname(fileURLToPath(import.meta.url));
const root = join(here, "..", "..");
const require = createRequire(join(root, "assets", "package.json"));

const BASE = (process.env.NEPTUNUS_URL || "http://127.0.0.1:4000").replace(/\/+$/, "");
const CHROMIUM = process.env.CHROMIUM_PATH || "/usr/bin/chromium";
const ARTIFACTS = join(here, "artifacts");
const LOGINS = JSON.parse(process.env.NEPTUNUS_E2E_LOGINS || "{}");
const CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking"];

// bounds of waits for what must happen (generous: the machine may be busy), not speeds
const WAIT_MS = 15000;
// the main station's takeover waits 3 s for the pilot first
const TAKEOVER_WAIT_MS = 3000 + WAIT_MS;
const TEST_MS = 120000;

let browser;
const pageProblems = [];

before(async () => {
  for (const name of ["e2e-pilot", "e2e-main", "e2e-olga"]) {
    assert.equal(typeof LOGINS[name], "string", `NEPTUNUS_E2E_LOGINS has no password for ${name}`);
  }
  assert.ok(existsSync(CHROMIUM), `no Chromium at ${CHROMIUM}`);
  const session = await fetch(`${BASE}/api/session`, { signal: AbortSignal.timeout(WAIT_MS) }).then((r) => r.json());
  assert.equal(session.mode, "secure", `the server must run in secure mode for this test: ${JSON.stringify(session)}`);
  mkdirSync(ARTIFACTS, { recursive: true });
  browser = await require("playwright-core").chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, timeout: 30000 });
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

async function newPage(label) {
  const context = await browser.newContext({ viewport: { width: 1280, height: 800 } });
  context.setDefaultTimeout(WAIT_MS);
  await recordMessages(context);
  // Content-Security-Policy violations become console errors, which are problems
  await context.addInitScript(() => {
    document.addEventListener("securitypolicyviolation", (e) => {
      console.error(`CSP violation: ${e.violatedDirective} blocked ${e.blockedURI || "inline"} (${e.sourceFile}:${e.lineNumber})`);
    });
  });
  const page = await context.newPage();
  page.on("pageerror", (err) => pageProblems.push(`[${label}] uncaught: ${err.message}`));
  page.on("console", (msg) => {
    // the wrong password's 401 is logged by the browser itself; anything else is a problem
    const expected = /status of 401 \(Unauthorized\)/.test(msg.text());
    if (msg.type() === "error" && !expected) pageProblems.push(`[${label}] console.error: ${msg.text()}`);
  });
  return { context, page };
}

/** Opens the operator page, is sent to the login page, logs in, comes back connected. */
async function loginAs(name, { wrongFirst = false } = {}) {
  const { context, page } = await newPage(name);
  await page.goto(`${BASE}/`, { waitUntil: "load" });
  await page.waitForURL(/\/login\.html\?next=%2F/, { timeout: WAIT_MS });
  if (wrongFirst) {
    await page.locator("#login-name").fill(name);
    await page.locator("#login-password").fill("not the password");
    await page.locator("#login-submit").click();
    await page.locator('#message[data-kind="error"]', { hasText: "wrong name or password" }).waitFor();
  }
  await page.locator("#login-name").fill(name);
  await page.locator("#login-password").fill(LOGINS[name]);
  await page.locator("#login-submit").click();
  await page.waitForURL(`${BASE}/`, { timeout: WAIT_MS });
  await page.locator('#status[data-state="connected"]').waitFor();
  await page.locator("#mode-banner", { hasText: `Signed in as ${name}` }).waitFor();
  return { context, page };
}

const helm = (page) => page.locator("#helm-state");

/**
 * No page of this test reported an error, up to and including its closing (each test
 * checks after it has closed its pages, so what a page says as it closes is its own test's).
 */
function assertNoPageProblems() {
  const problems = pageProblems.splice(0);
  assert.deepEqual(problems, [], `the pages reported errors:\n${problems.join("\n")}`);
}

test("login, roles, and the main station's takeover with a warning", { timeout: TEST_MS }, async () => {
  const pilot = await loginAs("e2e-pilot", { wrongFirst: true });
  const olga = await loginAs("e2e-olga");
  const main = await loginAs("e2e-main");
  try {
    await pilot.page.screenshot({ path: join(ARTIFACTS, "login-pilot.png") });

    // the pilot takes the free helm
    await pilot.page.locator("#request-control:enabled").click();
    await pilot.page.locator('#helm-state[data-me="pilot"]').waitFor();

    // an observer watches and cannot ask
    await olga.page.locator("#mode-banner", { hasText: "(observer)" }).waitFor();
    await olga.page.locator('#helm-state', { hasText: "e2e-pilot pilots" }).waitFor();
    assert.equal(await olga.page.locator("#request-control").isDisabled(), true, "an observer may not request control");
    assert.equal(await olga.page.locator("#take-control").isVisible(), false);

    // the main station takes control: both are warned, with a countdown, before the transfer
    const shownBefore = await messageCount(pilot.page);
    await main.page.locator("#take-control").click();
    await pilot.page.locator('#helm-state[data-state="takeover"][data-warning="true"]').waitFor();
    assert.match((await helm(pilot.page).textContent()) ?? "", /Main station e2e-main takes control from you in \d s/);
    await main.page.locator('#helm-state[data-me="taking_over"][data-warning="true"]').waitFor();
    await olga.page.locator('#helm-state[data-state="takeover"][data-warning="false"]').waitFor();
    await pilot.page.screenshot({ path: join(ARTIFACTS, "takeover-warning.png") });

    await main.page.locator('#helm-state[data-me="pilot"]').waitFor({ timeout: TAKEOVER_WAIT_MS });
    await messageShown(pilot.page, "main_station_takeover", shownBefore);
    await pilot.page.locator('#helm-state[data-me="watching"]').waitFor();
    assert.equal(await olga.page.locator("#pilot").textContent(), "e2e-main");

    // signing out forgets the token: the operator page asks for a login again
    await pilot.page.locator("#sign-out").click();
    await pilot.page.waitForURL(/\/login\.html/);
    await pilot.page.goto(`${BASE}/`);
    await pilot.page.waitForURL(/\/login\.html\?next=/);
  } finally {
    for (const side of [pilot, olga, main]) await side.context.close();
  }
  assertNoPageProblems();
});

test("developer page in secure mode: to the login page and back; each user's plots are their own", { timeout: TEST_MS }, async () => {
  const openDev = async (name) => {
    const side = await newPage(`${name}-dev`);
    await side.page.goto(`${BASE}/dev.html`, { waitUntil: "load" });
    await side.page.waitForURL(/\/login\.html\?next=%2Fdev\.html/, { timeout: WAIT_MS });
    await side.page.locator("#login-name").fill(name);
    await side.page.locator("#login-password").fill(LOGINS[name]);
    await side.page.locator("#login-submit").click();
    await side.page.waitForURL(`${BASE}/dev.html`, { timeout: WAIT_MS });
    await side.page.locator('#status[data-state="connected"]').waitFor();
    return side;
  };
  const status = (page) => page.locator("#plots-status").getAttribute("data-state");
  const count = (page) => page.locator('[data-testid="plot"]').count();
  const waitFor = async (read, pred, what) => {
    const deadline = Date.now() + WAIT_MS;
    for (;;) {
      const v = await read();
      if (pred(v)) return v;
      assert.ok(Date.now() < deadline, `timed out waiting for ${what}; last: ${JSON.stringify(v)}`);
      await new Promise((r) => setTimeout(r, 50));
    }
  };
  const olga = await openDev("e2e-olga");
  try {
    await olga.page.locator("#reset-plots").click();
    await waitFor(() => status(olga.page), (s) => s === "default", "olga's default plots");
    // the vehicle has a position source: the default set includes position once telemetry says so
    await olga.page.locator('[data-testid="plot"][data-series="position.north,position.east"]').waitFor();
    const defaults = await count(olga.page);
    assert.ok(defaults >= 4, `the default set has ${defaults} plots`);
    await olga.page.locator("#remove-plots").click();
    await waitFor(() => status(olga.page), (s) => s === "saved", "olga's plots saved");
    // another user on another device: their own (default) plots, not olga's
    const pilot = await openDev("e2e-pilot");
    try {
      await waitFor(() => status(pilot.page), (s) => s === "default" || s === "stored", "the pilot's plots");
      if ((await status(pilot.page)) === "stored") {
        await pilot.page.locator("#reset-plots").click();
        await waitFor(() => status(pilot.page), (s) => s === "default", "the pilot's default plots");
      }
      await pilot.page.locator('[data-testid="plot"][data-series="position.north,position.east"]').waitFor();
      assert.equal(await count(pilot.page), defaults);
    } finally {
      await pilot.context.close();
    }
    // olga's choice is kept for her: a new device of hers opens with no plots
    const again = await openDev("e2e-olga");
    try {
      await waitFor(() => status(again.page), (s) => s === "stored", "olga's stored plots");
      assert.equal(await count(again.page), 0);
      await again.page.locator("#reset-plots").click();
      await waitFor(() => status(again.page), (s) => s === "default", "olga's defaults again");
    } finally {
      await again.context.close();
    }
  } finally {
    await olga.context.close();
  }
  assertNoPageProblems();
});
