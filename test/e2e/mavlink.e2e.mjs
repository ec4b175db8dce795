// Browser test of the operator page flying a mavlink (ArduSub) vehicle against the fake ArduSub
// (test/support/fake_ardusub.py): the Vehicle panel shows link, armed state and flight mode;
// the pilot arms, drives with the keyboard, stops and disarms. Run from ExUnit
// (test/neptunus_web/mavlink_e2e_test.exs), which starts the fake and the vehicle and checks
// what the fake received:
//
//   NEPTUNUS_URL=http://127.0.0.1:4102 E2E_MAVLINK_VEHICLE=sub node --test test/e2e/mavlink.e2e.mjs

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import { DESKTOP, TEST_MS, WAIT_MS, assertNoPageProblems, helmState, launch, messageCount, messageShown, num, open, screenshot, takeHelm, thrusterValues, until } from "./helpers.mjs";

const VEHICLE = process.env.E2E_MAVLINK_VEHICLE;
let browser;

before(async () => {
  assert.ok(VEHICLE, "set E2E_MAVLINK_VEHICLE to the mavlink vehicle's id");
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

const armed = (page) => page.locator("#armed").getAttribute("data-armed");

test("a mavlink vehicle: link, mode, arm, drive, stop, disarm from the operator page", { timeout: TEST_MS }, async () => {
  const path = `/?vehicle=${encodeURIComponent(VEHICLE)}&name=e2e-mav`;
  const { context, page } = await open(browser, { ...DESKTOP, name: "e2e-mav", path });
  try {
    // the vehicle's own state, from its heartbeat
    await page.locator("#vehicle-link", { hasText: "up" }).waitFor();
    await page.locator("#vehicle-mode", { hasText: "MANUAL" }).waitFor();
    // its frame (FRAME_CONFIG), which decides whether it sways: the fake is a vectored one
    await page.locator("#vehicle-frame", { hasText: "Vectored" }).waitFor();
    assert.equal(await armed(page), "false");
    // telemetry from ATTITUDE / VFR_HUD
    await page.waitForFunction(() => /^\d+\.\d$/.test(document.querySelector("#heading")?.textContent ?? ""), null, { timeout: WAIT_MS });

    // only the pilot sees Arm / Disarm
    assert.equal(await page.locator("#arm").isVisible(), false);
    await takeHelm(page);
    assert.equal((await helmState(page)).me, "pilot");
    const beforeArm = await messageCount(page);
    await page.locator("#arm:enabled").click();
    await until(() => armed(page), (a) => a === "true", WAIT_MS, "the vehicle armed");
    await messageShown(page, "Vehicle armed", beforeArm);

    // keyboard: W drives forward; the page shows the command and thrusters
    await page.locator("#input-keyboard").click();
    await page.keyboard.down("KeyW");
    try {
      await until(() => num(page, "#cmd-surge"), (v) => v > 0, WAIT_MS, "commanded surge > 0 while W is held");
      await page.waitForTimeout(700);
      await screenshot(page, "operator-mavlink.png");
    } finally {
      await page.keyboard.up("KeyW");
    }
    await until(() => thrusterValues(page), (t) => t.port === 0 && t.starboard === 0, WAIT_MS, "thrusters back to 0 after W");

    // an ArduSub vehicle sways: the page shows the axis, C strafes to starboard
    await page.locator("#cmd-sway").waitFor();
    await page.keyboard.down("KeyC");
    try {
      await until(() => num(page, "#cmd-sway"), (v) => v > 0, WAIT_MS, "commanded sway > 0 while C is held");
    } finally {
      await page.keyboard.up("KeyC");
    }
    await until(() => num(page, "#cmd-sway"), (v) => v === 0, WAIT_MS, "sway back to 0 after C");

    // stop, then disarm
    await page.locator("#stop").click();
    const beforeDisarm = await messageCount(page);
    await page.locator("#disarm:enabled").click();
    await until(() => armed(page), (a) => a === "false", WAIT_MS, "the vehicle disarmed");
    await messageShown(page, "Vehicle disarmed", beforeDisarm);
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});
