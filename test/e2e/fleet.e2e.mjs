// Browser test of a fleet: headless Debian Chromium (playwright-core) on the operator page of
// one node (T) picks a vehicle that runs on another node (V) and flies it; on a touch tablet,
// the fleet overview shows it live and a tap opens it.
//
//   FLEET_VEHICLE=<id on V> FLEET_NODE=<V's node name> NEPTUNUS_URL=<T's url> \
//     node --test test/e2e/fleet.e2e.mjs
//
// Run by test/neptunus_web/fleet_cluster_test.exs, which starts V. Every wait has a timeout;
// the browser is closed in `after`.

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import { DESKTOP, TABLET, TEST_MS, WAIT_MS, assertNoPageProblems, launch, open, screenshot, takeHelm, until, waitTelemetry } from "./helpers.mjs";

const VEHICLE = process.env.FLEET_VEHICLE;
const NODE = process.env.FLEET_NODE;

let browser;

before(async () => {
  assert.ok(VEHICLE && NODE, "set FLEET_VEHICLE and FLEET_NODE");
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

test("the picker lists the vehicle of the other node; picking it opens it, and it flies", { timeout: TEST_MS }, async () => {
  // the page starts on this node's own vehicle
  const { context, page } = await open(browser, { ...DESKTOP, name: "fleet-picker", path: "/?name=fleet-picker&vehicle=neptunus-1" });
  try {
    const picker = page.locator("#vehicle-picker");
    await picker.waitFor({ timeout: WAIT_MS });
    const option = picker.locator(`option[value="${VEHICLE}"]`);
    assert.match((await option.textContent()) ?? "", new RegExp(`on ${NODE.replace(/[.]/g, "\\.")}`));

    await Promise.all([page.waitForURL((url) => url.searchParams.get("vehicle") === VEHICLE, { timeout: WAIT_MS }), picker.selectOption(VEHICLE)]);
    await page.locator('#status[data-state="connected"]').waitFor({ timeout: WAIT_MS });
    assert.equal(await page.locator("#vehicle-id").textContent(), VEHICLE);
    assert.equal(new URL(page.url()).searchParams.get("name"), "fleet-picker");
    await waitTelemetry(page);
    await takeHelm(page);
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

// the overview's row of the vehicle on V: its fields as the page shows them
async function overviewRow(page) {
  const row = page.locator(`#fleet-overview a[data-vehicle="${VEHICLE}"]`);
  const field = async (name) => ((await row.locator(`[data-field="${name}"]`).textContent()) ?? "").trim();
  return {
    status: await row.getAttribute("data-status"),
    node: ((await row.locator(".fleet-node").textContent()) ?? "").trim(),
    depth: await field("depth"),
    heading: await field("heading"),
    pilot: await field("pilot"),
    link: await field("link"),
  };
}

test("the fleet overview on a 1024×768 touch tablet: the vehicle on V, live; a tap opens it", { timeout: TEST_MS }, async () => {
  const tablet = await open(browser, { ...TABLET, touch: true, name: "fleet-tablet", path: "/?name=fleet-tablet&vehicle=neptunus-1" });
  let pilot = null;
  try {
    const { page } = tablet;
    const row = page.locator(`#fleet-overview a[data-vehicle="${VEHICLE}"]`);
    await row.waitFor({ timeout: WAIT_MS });
    assert.ok(await row.isVisible(), "the overview's row is visible on the tablet");
    const box = await row.boundingBox();
    assert.ok(box && box.height >= 44 && box.x >= 0 && box.x + box.width <= TABLET.width, `a row fits a finger and the screen: ${JSON.stringify(box)}`);
    assert.equal(await page.locator('#fleet-overview a[data-vehicle="neptunus-1"]').getAttribute("aria-current"), "page");

    const first = await until(() => overviewRow(page), (r) => r.depth.endsWith(" m") && r.heading.endsWith("°"), 10_000, "depth and heading of the vehicle on V");
    assert.equal(first.status, "up");
    assert.equal(first.node, NODE);
    assert.equal(first.link, "link up");

    // a pilot takes the vehicle on V from another page: the overview says who, live
    pilot = await open(browser, { ...DESKTOP, name: "fleet-pilot", path: `/?name=fleet-pilot&vehicle=${encodeURIComponent(VEHICLE)}` });
    await waitTelemetry(pilot.page);
    await takeHelm(pilot.page);
    await until(() => overviewRow(page), (r) => r.pilot === "fleet-pilot", 10_000, "the pilot's name in the overview");
    await screenshot(page, "fleet-overview-tablet.png", { fullPage: false });

    await Promise.all([page.waitForURL((url) => url.searchParams.get("vehicle") === VEHICLE, { timeout: WAIT_MS }), row.tap()]);
    await page.locator('#status[data-state="connected"]').waitFor({ timeout: WAIT_MS });
    assert.equal(await page.locator("#vehicle-id").textContent(), VEHICLE);
    assert.equal(new URL(page.url()).searchParams.get("name"), "fleet-tablet");
    await waitTelemetry(page);
    await page.locator(`#fleet-overview a[data-vehicle="${VEHICLE}"][aria-current="page"]`).waitFor({ timeout: WAIT_MS });
    assertNoPageProblems();
  } finally {
    await pilot?.context.close();
    await tablet.context.close();
  }
});
