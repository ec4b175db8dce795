// A ground station and a browser on one vehicle: MAVProxy (PyPI, in the project's .venv, driven
// through its standard input) connects to Neptunus' MAVLink endpoint, lists and sets parameters,
// watches the vehicle dive under a browser pilot (Chromium), asks for the helm, is allowed by
// that pilot, arms and drives with MANUAL_CONTROL while the browser watches it fly, and goes
// silent: the vehicle stops. Run from ExUnit (test/neptunus_web/gcs_external_test.exs), which
// serves the endpoint and the vehicle:
//
//   NEPTUNUS_URL=http://127.0.0.1:4102 E2E_GCS_VEHICLE=rov E2E_GCS_PORT=14560 \
//     MAVPROXY=.venv/bin/mavproxy.py node --test test/e2e/gcs.e2e.mjs

import assert from "node:assert/strict";
import { spawn } from "node:child_process";
import { mkdtempSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { after, before, test } from "node:test";
import { fileURLToPath } from "node:url";
import { DESKTOP, TEST_MS, WAIT_MS, allZero, helmState, launch, num, open, screenshot, takeHelm, thrusterValues, until, waitTelemetry } from "./helpers.mjs";

const VEHICLE = process.env.E2E_GCS_VEHICLE;
const PORT = process.env.E2E_GCS_PORT;
const MAVPROXY = process.env.MAVPROXY;
const here = dirname(fileURLToPath(import.meta.url));
let browser;

before(async () => {
  assert.ok(VEHICLE && PORT && MAVPROXY, "set E2E_GCS_VEHICLE, E2E_GCS_PORT and MAVPROXY");
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

/** MAVProxy on the endpoint, headless: commands in on stdin, what it prints kept. */
function mavproxy() {
  const proc = spawn(
    MAVPROXY,
    [
      `--master=udpout:127.0.0.1:${PORT}`,
      "--no-state",
      "--default-modules=link,param,cmdlong,arm,mode,misc,signing",
      "--load-module=mavproxy_neptunus",
    ],
    {
      cwd: mkdtempSync(join(tmpdir(), "mavproxy-")),
      env: { ...process.env, PYTHONPATH: join(here, "..", "support"), MAVLINK20: "1", PYTHONUNBUFFERED: "1" },
      stdio: ["pipe", "pipe", "pipe"],
    },
  );
  const out = { text: "", proc };
  proc.stdout.on("data", (d) => (out.text += d.toString()));
  proc.stderr.on("data", (d) => (out.text += d.toString()));
  out.send = (line) => proc.stdin.write(line + "\n");
  /** Waits until MAVProxy has printed something matching `re` after position `from`; the match. */
  out.expect = async (re, ms = WAIT_MS, from = 0) => {
    const found = await until(() => out.text.slice(from).match(re), (m) => m !== null, ms, `MAVProxy printing ${re} (it printed:\n${out.text.slice(-2000)})`);
    return found;
  };
  /** The fields of the last `status NAME` MAVProxy prints, as numbers. */
  out.status = async (name) => {
    const from = out.text.length;
    out.send(`status ${name}`);
    const m = await out.expect(new RegExp(`${name} \\{([^}]*)\\}`), WAIT_MS, from);
    return Object.fromEntries(m[1].split(",").map((kv) => kv.split(":").map((s) => s.trim())).map(([k, v]) => [k, Number(v)]));
  };
  /** The value MAVProxy holds for parameter `name` (`param show`; a set lands asynchronously). */
  out.show = async (name) => {
    const from = out.text.length;
    out.send(`param show ${name}`);
    const m = await out.expect(new RegExp(`${name}\\s+(-?[0-9.]+)`), WAIT_MS, from);
    return Number(m[1]);
  };
  return out;
}

async function hold(page, codes, ms) {
  for (const c of codes) await page.keyboard.down(c);
  try {
    await page.waitForTimeout(ms);
  } finally {
    for (const c of codes) await page.keyboard.up(c);
  }
}

test("MAVProxy: parameters, the dive seen, the helm asked of a browser pilot and given, arm, drive, silence stops", { timeout: 3 * TEST_MS }, async () => {
  const gcs = mavproxy();
  const { context, page } = await open(browser, { ...DESKTOP, name: "e2e-pilot", path: `/?vehicle=${encodeURIComponent(VEHICLE)}&name=e2e-pilot` });
  try {
    await gcs.expect(/online system \d+/, 2 * WAIT_MS);
    await waitTelemetry(page);

    // parameters: the list, and a set refused while it does not pilot (the old value comes back)
    gcs.send("param fetch");
    await gcs.expect(/Received 16 parameters/, 2 * WAIT_MS);
    gcs.send("param show PILOT_GAIN");
    await gcs.expect(/PILOT_GAIN\s+0\.5/);
    gcs.send("param set LIGHTS 40");
    await gcs.expect(/LIGHTS refused: not in control/);

    // the browser takes the helm and dives, turning: MAVProxy sees depth and attitude change
    await takeHelm(page);
    const before = { hud: await gcs.status("VFR_HUD"), attitude: await gcs.status("ATTITUDE") };
    await page.locator("#input-keyboard").click();
    const depth0 = await num(page, "#depth");
    await page.keyboard.down("KeyQ");
    await page.keyboard.down("KeyD");
    try {
      await until(() => num(page, "#depth"), (d) => d > depth0 + 0.3, 4 * WAIT_MS, "the vehicle diving under the browser pilot");
    } finally {
      await page.keyboard.up("KeyQ");
      await page.keyboard.up("KeyD");
    }
    await until(() => gcs.status("VFR_HUD"), (h) => h.alt < before.hud.alt - 0.25, WAIT_MS, "MAVProxy seeing the depth (altitude = -depth)");
    const attitude = await gcs.status("ATTITUDE");
    assert.ok(Math.abs(attitude.yaw - before.attitude.yaw) > 0.05, `yaw ${before.attitude.yaw} → ${attitude.yaw}`);

    // MAVProxy asks for the helm (MAV_CMD_REQUEST_OPERATOR_CONTROL): the pilot is asked
    let from = gcs.text.length;
    gcs.send("long 32100 0 1 0 10");
    await gcs.expect(/COMMAND_ACK \{command : 32100, result : 5/, WAIT_MS, from);
    await page.locator("#control-request", { hasText: "gcs-255" }).waitFor();
    await screenshot(page, "gcs-request.png");
    await page.locator("#accept-request").click();
    await gcs.expect(/COMMAND_ACK \{command : 32100, result : 0/, WAIT_MS, from);
    await page.locator('#helm-state[data-me="watching"]').waitFor();
    await until(() => helmState(page), (h) => h.text.includes("gcs-255"), WAIT_MS, "the page naming the ground station as pilot");

    // it sets the parameter now, arms and drives with MANUAL_CONTROL; the browser sees it fly
    from = gcs.text.length;
    gcs.send("param set LIGHTS 40");
    await until(() => gcs.show("LIGHTS"), (v) => v === 40, 2 * WAIT_MS, "MAVProxy holding LIGHTS 40 (its set accepted)");
    gcs.send("arm throttle");
    await gcs.expect(/COMPONENT_ARM_DISARM: ACCEPTED/, WAIT_MS, from);
    gcs.send("stick 700 0 500 0");
    await until(() => num(page, "#cmd-surge"), (v) => v > 0.5, WAIT_MS, "the browser seeing the ground station's surge");
    await until(() => thrusterValues(page), (t) => t.port > 0 && t.starboard > 0, WAIT_MS, "thrusters pushing forward");
    await screenshot(page, "gcs-flying.png");

    // silence: the ground station stops streaming its stick, the deadman stops the vehicle
    gcs.send("stick stop");
    await until(() => thrusterValues(page), allZero, WAIT_MS, "neutral after the ground station's silence");
    await gcs.expect(/stopped: deadman/, WAIT_MS, from);
  } finally {
    // MAVProxy's own signal handling may keep it up: kill it outright, so node can exit
    gcs.proc.stdin.end();
    gcs.proc.kill("SIGKILL");
    await context.close();
  }
});
