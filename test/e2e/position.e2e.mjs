// Browser test of position, position hold and missions on the operator page's map: headless
// Debian Chromium (playwright-core) against a running Neptunus server with a simulated vehicle
// that has the simulated DVL and USBL (read by the real drivers over their protocols) and a
// water current. ExUnit starts that vehicle and names it in E2E_POSITION_VEHICLE
// (test/e2e/external_test.exs); by hand:
//
//   NEPTUNUS_URL=http://127.0.0.1:4102 E2E_POSITION_VEHICLE=neptunus-1 node --test test/e2e/position.e2e.mjs
//
// At the tablet's 1024×768 with touch: the pilot dives with the depth autopilot, the map shows
// a valid position with its ellipse and sources, DP holds it against the current (the
// distance to the target is sampled for a while), and a two-waypoint mission planned on the
// map — one waypoint tapped, one clicked — is flown to its end, then held. The figures
// measured are printed (diagnostics, not timing assertions).

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import { TABLET, WAIT_MS, assertNoPageProblems, launch, open, screenshot, takeHelm, until, waitTelemetry } from "./helpers.mjs";

const VEHICLE = process.env.E2E_POSITION_VEHICLE || "neptunus-1";
const HOLD_SAMPLE_MS = 20_000;
const MISSION_MS = 150_000;

let browser;

before(async () => {
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

async function position(page) {
  const el = page.locator("#position-text");
  return {
    valid: (await el.getAttribute("data-valid")) === "true",
    north: Number.parseFloat((await el.getAttribute("data-north")) ?? ""),
    east: Number.parseFloat((await el.getAttribute("data-east")) ?? ""),
    text: (await el.textContent()) ?? "",
  };
}

async function text(page, selector) {
  return ((await page.locator(selector).textContent()) ?? "").trim();
}

/** The page (client) coordinates of a map point, from the map's own projection. */
async function onMap(page, p) {
  const svg = page.locator("#map");
  await svg.scrollIntoViewIfNeeded();
  const box = await svg.boundingBox();
  assert.ok(box, "the map has no box");
  const n0 = Number(await svg.getAttribute("data-centre-north"));
  const e0 = Number(await svg.getAttribute("data-centre-east"));
  const scale = Number(await svg.getAttribute("data-scale"));
  const [, , w, h] = ((await svg.getAttribute("viewBox")) ?? "").split(" ").map(Number);
  const x = w / 2 + (p.east - e0) * scale;
  const y = h / 2 - (p.north - n0) * scale;
  assert.ok(x > 0 && x < w && y > 0 && y < h, `(${p.north}, ${p.east}) is off the map`);
  return { x: box.x + (x / w) * box.width, y: box.y + (y / h) * box.height };
}

function p95(values) {
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.min(sorted.length - 1, Math.floor(0.95 * sorted.length))];
}

test("a simulated vehicle dives with a position, holds it in DP against the current, and flies a two-waypoint mission planned on the map", { timeout: 300_000 }, async () => {
  const { context, page } = await open(browser, { ...TABLET, touch: true, name: "e2e-position", path: `/?vehicle=${encodeURIComponent(VEHICLE)}&name=e2e-position` });
  try {
    await waitTelemetry(page);

    // the position: valid once the DVL and the USBL have reported and agreed
    const first = await until(() => position(page), (p) => p.valid, 30_000, "a valid position");
    assert.match(first.text, /^N -?\d+\.\d\d m, E -?\d+\.\d\d m ± \d+\.\d\d m/);
    await page.locator('[data-testid="map-ellipse"]').waitFor();
    await page.locator('[data-testid="map-vehicle"]').waitFor();
    await page.locator('[data-testid="source-dvl"][data-state="valid"]').waitFor({ timeout: 15_000 });
    await page.locator('[data-testid="source-usbl"][data-state="valid"]').waitFor({ timeout: 15_000 });
    // not piloting: no plan by touch, the buttons are off
    await page.locator("#map-start:disabled").waitFor();

    await takeHelm(page);

    // dive with the depth autopilot
    await page.locator("#depth-input").fill("2");
    await page.locator("#depth-set").click();
    await until(async () => Number.parseFloat(await text(page, "#depth")), (d) => Math.abs(d - 2) < 0.3, 60_000, "the vehicle at 2 m");

    // DP: it holds the position where it is, against the current
    await page.locator("#control-mode-dp").click();
    await page.locator('#control-mode-dp[aria-checked="true"]').waitFor();
    await page.locator('[data-testid="map-target"]').waitFor();
    await until(() => text(page, "#dp-phase"), (t) => t === "hold" || t === "return", WAIT_MS, "DP holding");
    const distances = [];
    const t0 = Date.now();
    while (Date.now() - t0 < HOLD_SAMPLE_MS) {
      const d = Number.parseFloat(await text(page, "#dp-distance"));
      if (Number.isFinite(d)) distances.push(d);
      await page.waitForTimeout(250);
    }
    assert.ok(distances.length > 10, "too few distance samples");
    const holdP95 = p95(distances);
    console.log(`position hold against the current: distance p95 ${holdP95.toFixed(2)} m, max ${Math.max(...distances).toFixed(2)} m over ${distances.length} samples`);
    // a three-thruster vehicle keeps within its 1 m radius; the bound allows for a loaded machine
    assert.ok(holdP95 < 2.5, `DP drifted: distance p95 ${holdP95.toFixed(2)} m`);
    assert.equal(await page.locator("#position-text").getAttribute("data-valid"), "true");
    await screenshot(page, "position-hold-tablet.png");

    // a mission planned on the map: one waypoint tapped, one clicked
    const here = await position(page);
    const wp1 = { north: here.north + 3, east: here.east };
    const wp2 = { north: here.north + 3, east: here.east + 3 };
    const a = await onMap(page, wp1);
    await page.touchscreen.tap(a.x, a.y);
    await until(() => page.locator('[data-testid="map-plan-point"]').count(), (n) => n === 1, WAIT_MS, "the tapped waypoint");
    const b = await onMap(page, wp2);
    await page.mouse.click(b.x, b.y);
    await until(() => page.locator('[data-testid="map-plan-point"]').count(), (n) => n === 2, WAIT_MS, "the clicked waypoint");
    assert.match(await text(page, "#map-start"), /Start mission \(2\)/);
    await page.locator("#map-start").click();
    await page.locator('#mission-state[data-state="running"]').waitFor();
    assert.equal(await page.locator('[data-testid="map-waypoint"]').count(), 2);
    assert.equal(await page.locator('[data-testid="map-plan-point"]').count(), 0);

    const crossTrack = [];
    await until(
      async () => {
        const ct = Number.parseFloat(await text(page, "#cross-track"));
        if (Number.isFinite(ct)) crossTrack.push(Math.abs(ct));
        return page.locator("#mission-state").getAttribute("data-state");
      },
      (state) => state === "done",
      MISSION_MS,
      "the mission done",
    );
    const end = await position(page);
    const off = Math.hypot(end.north - wp2.north, end.east - wp2.east);
    console.log(`mission: cross-track p95 ${crossTrack.length ? p95(crossTrack).toFixed(2) : "—"} m over ${crossTrack.length} samples; ended ${off.toFixed(2)} m from the last waypoint`);
    assert.ok(off < 2.0, `the mission ended ${off.toFixed(2)} m from its last waypoint`);
    // done: DP holds the last waypoint
    await until(() => text(page, "#dp-phase"), (t) => t === "hold" || t === "return", WAIT_MS, "DP holding the last waypoint");
    const track = Number(await page.locator('[data-testid="map-track"]').getAttribute("data-points"));
    assert.ok(track > 10, `the track has ${track} points`);
    await screenshot(page, "position-mission-tablet.png");

    await page.locator("#release-control").click().catch(() => undefined);
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});
