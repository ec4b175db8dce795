// Browser test of a fleet: headless Debian Chromium (playwright-core) on the operator page of
// one node (T) picks a vehicle that runs on another node (V) and flies it.
//
//   FLEET_VEHICLE=<id on V> FLEET_NODE=<V's node name> NEPTUNUS_URL=<T's url> \
//     node --test test/e2e/fleet.e2e.mjs
//
// Run by test/neptunus_web/fleet_cluster_test.exs, which starts V. Every wait has a timeout;
// the browser is closed in `after`.

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import { DESKTOP, TEST_MS, WAIT_MS, assertNoPageProblems, launch, open, takeHelm, waitTelemetry } from "./helpers.mjs";

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
