// Browser tests of the operator page: headless Debian Chromium (playwright-core) against a
// running Neptunus server with a simulated vehicle, at desktop (1920×1080) and tablet
// (1024×768, touch emulation) viewports.
//
//   (cd assets && npm install && npm run build)
//   NEPTUNUS_URL=http://127.0.0.1:4102 node --test test/e2e/operator.e2e.mjs
//
// Every wait has a timeout; the browser is closed in `after`, so the process exits whether the
// server is there or not. Screenshots: test/e2e/artifacts/.

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import {
  BASE,
  DESKTOP,
  TABLET,
  TEST_MS,
  WAIT_MS,
  allZero,
  afterFrames,
  assertNoPageProblems,
  helmState,
  launch,
  messageCount,
  messageShown,
  num,
  open,
  pressButton,
  screenshot,
  stubPad,
  takeHelm,
  thrusterValues,
  until,
  waitTelemetry,
} from "./helpers.mjs";

let browser;

before(async () => {
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

async function operator(opts) {
  const side = await open(browser, opts);
  await waitTelemetry(side.page);
  return side;
}

async function hold(page, code, ms) {
  await page.keyboard.down(code);
  try {
    await page.waitForTimeout(ms);
  } finally {
    await page.keyboard.up(code);
  }
}

test("keyboard: request control, keys drive the vehicle, request → deny → accept handover between two browsers", { timeout: TEST_MS }, async () => {
  const { context, page } = await operator({ ...DESKTOP, name: "e2e-desktop" });
  try {
    assert.match((await page.locator("#vehicle-id").textContent()) ?? "", /\S/);
    assert.match((await page.locator("#mode-banner").textContent()) ?? "", /Local mode/);
    // the simulated vehicle has the sim camera, played over the video socket
    await page.locator('[data-testid="camera"][data-camera="on"] [data-testid="video-feed"]').waitFor();
    // the HUD's depth: a number once the server says it is valid ("initialising" before, never a number)
    const depth = page.locator('[data-testid="hud-depth"]');
    await until(() => depth.getAttribute("data-state"), (state) => state === "valid", WAIT_MS, "a valid depth");
    assert.match((await depth.textContent()) ?? "", /^-?\d+\.\d\d$/);
    await page.locator("#input-keyboard").click();

    // not in control yet: keys do nothing
    await until(() => helmState(page), (h) => h.state === "free", WAIT_MS, "a free helm");
    assert.ok(allZero(await thrusterValues(page)), "thrusters must be at zero before we press anything");
    await hold(page, "KeyW", 150);
    await page.locator("#message", { hasText: "Not in control" }).waitFor();

    await takeHelm(page);
    assert.equal((await helmState(page)).text, "You pilot");
    assert.equal(await page.locator("#pilot").textContent(), "e2e-desktop");

    // W: surge forward, held longer than the deadman (the page's heartbeats keep it going)
    const start = { x: await num(page, "#x"), y: await num(page, "#y") };
    await page.keyboard.down("KeyW");
    try {
      await until(() => num(page, "#cmd-surge"), (v) => v > 0, WAIT_MS, "commanded surge > 0 while W is held");
      await until(async () => (await thrusterValues(page)).port, (v) => v !== 0, WAIT_MS, "port thruster running");
      await page.waitForTimeout(700);
      assert.ok((await num(page, "#cmd-surge")) > 0, "surge dropped while W was held (deadman?)");
      // the heartbeat replies give a round-trip time
      await until(async () => (await page.locator("#rtt").textContent()) ?? "", (t) => /ms$/.test(t), WAIT_MS, "an RTT");
      await screenshot(page, "operator-1920x1080.png");
    } finally {
      await page.keyboard.up("KeyW");
    }
    await until(() => thrusterValues(page), allZero, WAIT_MS, "thrusters back to 0 after releasing W");
    await until(
      async () => ({ x: await num(page, "#x"), y: await num(page, "#y") }),
      (r) => Math.hypot(r.x - start.x, r.y - start.y) >= 0.01,
      WAIT_MS,
      "the position to change",
    );

    // a second operator (tablet) watches, is refused, asks, is denied, asks again, is handed the helm
    const tablet = await operator({ ...TABLET, name: "e2e-tablet", touch: true });
    try {
      await until(() => helmState(tablet.page), (h) => h.text === "e2e-desktop pilots", WAIT_MS, "the tablet names the pilot");
      await until(() => num(page, "#observers"), (n) => n >= 2, WAIT_MS, "two connections watching");
      await tablet.page.locator("#input-keyboard").click();
      await hold(tablet.page, "KeyW", 150);
      await tablet.page.locator("#message", { hasText: "Not in control" }).waitFor();
      assert.ok(allZero(await thrusterValues(page)), "a refused operator moved the thrusters");

      await tablet.page.locator("#request-control:enabled").click();
      await page.locator("#control-request", { hasText: "e2e-tablet" }).waitFor();
      await page.locator("#deny-request").click();
      await tablet.page.locator("#message", { hasText: "refused: denied" }).waitFor();
      assert.equal((await helmState(page)).me, "pilot");

      await page.keyboard.down("KeyD");
      await until(() => num(page, "#cmd-yaw"), (v) => v > 0, WAIT_MS, "yaw while D is held");
      await tablet.page.locator("#request-control:enabled").click();
      await page.locator("#accept-request").click();
      await tablet.page.locator('#helm-state[data-me="pilot"]').waitFor();
      await until(() => thrusterValues(page), allZero, WAIT_MS, "neutral on transfer although D is still held");
      await page.keyboard.up("KeyD");
      await page.locator('#helm-state[data-me="watching"]').waitFor();
      assert.equal(await page.locator("#pilot").textContent(), "e2e-tablet");

      await tablet.page.keyboard.down("KeyW");
      try {
        await until(() => num(page, "#cmd-surge"), (v) => v > 0, WAIT_MS, "the new pilot's surge");
      } finally {
        await tablet.page.keyboard.up("KeyW");
      }
      await until(() => thrusterValues(page), allZero, WAIT_MS, "thrusters back to 0");

      const overflow = await tablet.page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
      assert.ok(overflow <= 0, `page is ${overflow}px wider than the 1024px viewport`);
      await screenshot(tablet.page, "operator-1024x768.png");

      // On the tablet's screen: the whole side column (helm, input, vehicle settings) and the
      // message bar; the settings scroll inside the column, the camera and the page stay.
      const fit = await tablet.page.evaluate(() => {
        window.scrollTo(0, 0);
        const rect = (sel) => document.querySelector(sel).getBoundingClientRect();
        const side = document.querySelector(".side-column");
        const before = rect(".camera").top;
        side.scrollTop = side.scrollHeight;
        const rotation = rect("#rotation");
        return {
          height: window.innerHeight,
          side: rect(".side-column").bottom,
          message: rect("#message").bottom,
          rotation: rotation.bottom,
          rotationTop: rotation.top,
          cameraMoved: rect(".camera").top - before,
          pageScroll: window.scrollY,
        };
      });
      assert.ok(fit.side <= fit.height, `side column ends at ${fit.side}px, below the ${fit.height}px screen`);
      assert.ok(fit.message <= fit.height, `message bar ends at ${fit.message}px, below the screen`);
      assert.ok(fit.rotationTop >= 0 && fit.rotation <= fit.height, `last setting not reachable: ${JSON.stringify(fit)}`);
      assert.equal(fit.cameraMoved, 0, "scrolling the side column moved the camera");
      assert.equal(fit.pageScroll, 0, "scrolling the side column scrolled the page");
      await screenshot(tablet.page, "operator-1024x768-screen.png", { fullPage: false });
      await tablet.page.locator("#release-control").click();
      await until(() => helmState(page), (h) => h.state === "free", WAIT_MS, "helm free after release");
    } finally {
      await tablet.context.close();
    }
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

test("safety: blur, a hidden page and an input mode change stop the vehicle, as another browser sees it", { timeout: TEST_MS }, async () => {
  const pilot = await operator({ ...DESKTOP, name: "e2e-pilot" });
  const watcher = await operator({ ...TABLET, name: "e2e-watcher", touch: true });
  try {
    await pilot.page.locator("#input-keyboard").click();
    await takeHelm(pilot.page);
    const stopsBy = async (reason, trigger) => {
      await pilot.page.keyboard.down("KeyD");
      try {
        await until(() => num(watcher.page, "#cmd-yaw"), (v) => v > 0, WAIT_MS, "the watcher sees yaw while D is held");
        const [watcherBefore, pilotBefore] = [await messageCount(watcher.page), await messageCount(pilot.page)];
        await trigger();
        // server-side: the other browser sees neutral thrust and the server's `stopped`
        await until(() => thrusterValues(watcher.page), allZero, WAIT_MS, `neutral after "${reason}" although D is held`);
        await messageShown(watcher.page, `Vehicle stopped: ${reason}`, watcherBefore);
        await messageShown(pilot.page, "top", pilotBefore);
      } finally {
        await pilot.page.keyboard.up("KeyD");
      }
    };
    await stopsBy("window lost focus", () => pilot.page.evaluate(() => window.dispatchEvent(new Event("blur"))));
    await stopsBy("page hidden", () =>
      pilot.page.evaluate(() => {
        Object.defineProperty(document, "visibilityState", { value: "hidden", configurable: true });
        document.dispatchEvent(new Event("visibilitychange"));
        Object.defineProperty(document, "visibilityState", { value: "visible", configurable: true });
      }),
    );
    await stopsBy("input mode changed", () => pilot.page.locator("#input-touch").click());
    assert.equal(await pilot.page.locator("#pilot").textContent(), "e2e-pilot", "the pilot keeps the helm after a safety stop");
    assertNoPageProblems();
  } finally {
    await pilot.context.close();
    await watcher.context.close();
  }
});

test("touch: two on-screen sticks at once on a 1024×768 tablet, no scrolling", { timeout: TEST_MS }, async () => {
  const { context, page } = await operator({ ...TABLET, name: "e2e-touch", touch: true });
  try {
    await page.locator("#input-touch").click();
    await takeHelm(page);
    const cdp = await context.newCDPSession(page);
    const box = async (sel) => {
      const b = await page.locator(sel).boundingBox();
      assert.ok(b, `${sel} is not visible`);
      return { x: b.x + b.width / 2, y: b.y + b.height / 2, r: b.width / 2 };
    };
    const right = await box("#stick-right");
    const left = await box("#stick-left");
    const touch = (type, points) => cdp.send("Input.dispatchTouchEvent", { type, touchPoints: points });
    const scroll0 = await page.evaluate(() => [window.scrollX, window.scrollY]);

    // right stick up: surge
    await touch("touchStart", [{ x: right.x, y: right.y, id: 1 }]);
    await touch("touchMove", [{ x: right.x, y: right.y - right.r * 0.8, id: 1 }]);
    await until(() => num(page, "#cmd-surge"), (v) => v > 0.5, WAIT_MS, "surge from the right stick");
    // a second finger on the left stick, down: heave (descend) while the first still holds surge
    await touch("touchStart", [
      { x: right.x, y: right.y - right.r * 0.8, id: 1 },
      { x: left.x, y: left.y, id: 2 },
    ]);
    await touch("touchMove", [
      { x: right.x, y: right.y - right.r * 0.8, id: 1 },
      { x: left.x, y: left.y + left.r * 0.9, id: 2 },
    ]);
    await until(
      async () => [await num(page, "#cmd-surge"), await num(page, "#cmd-heave")],
      ([s, h]) => s > 0.5 && h > 0.5,
      WAIT_MS,
      "surge and heave at once",
    );
    await until(async () => (await thrusterValues(page)).vertical, (v) => v !== 0, WAIT_MS, "vertical thruster running");
    await screenshot(page, "operator-touch-1024x768.png");
    // lift the first finger (touchEnd lists the points that lift): surge back to 0, heave stays
    await touch("touchEnd", [{ x: right.x, y: right.y - right.r * 0.8, id: 1 }]);
    await until(
      async () => [await num(page, "#cmd-surge"), await num(page, "#cmd-heave")],
      ([s, h]) => s === 0 && h > 0.5,
      WAIT_MS,
      "surge 0, heave held",
    );
    await touch("touchEnd", []);
    await until(() => thrusterValues(page), allZero, WAIT_MS, "neutral after lifting both fingers");
    const scroll1 = await page.evaluate(() => [window.scrollX, window.scrollY]);
    assert.deepEqual(scroll1, scroll0, "piloting scrolled the page");
    const style = await page.locator("#stick-left").evaluate((el) => {
      const s = getComputedStyle(el);
      return { touchAction: s.touchAction, userSelect: s.userSelect || s.webkitUserSelect };
    });
    assert.deepEqual(style, { touchAction: "none", userSelect: "none" });
    await page.locator("#release-control").click();
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

test("tablet 1024×768 touch: the sticks and their labels clear the HUD's boxes; the compass labels are whole; the grant message goes once driving", { timeout: TEST_MS }, async () => {
  const { context, page } = await operator({ ...TABLET, name: "e2e-tablet-hud", touch: true });
  try {
    await page.locator("#input-touch").click();
    await page.locator("#stick-right").waitFor();
    const layout = await page.evaluate(() => {
      const box = (el) => {
        const b = el.getBoundingClientRect();
        return { x: b.left, y: b.top, r: b.right, b: b.bottom, text: (el.textContent ?? "").trim().slice(0, 24) };
      };
      return {
        pad: ["#stick-left", "#stick-right", "#stick-left .stick-label", "#stick-right .stick-label"].map((sel) => ({ sel, ...box(document.querySelector(sel)) })),
        hud: [...document.querySelectorAll(".hud-left > *, .hud-right > *")].map(box),
      };
    });
    const overlap = (a, b) => a.x < b.r && b.x < a.r && a.y < b.b && b.y < a.b;
    for (const p of layout.pad) {
      for (const h of layout.hud) assert.ok(!overlap(p, h), `${p.sel} ${JSON.stringify(p)} overlaps the HUD's "${h.text}" ${JSON.stringify(h)}`);
    }

    // every heading the tape can show: its labels are whole, inside the tape
    const labels = () =>
      page.evaluate(() => {
        const tape = document.querySelector(".compass").getBoundingClientRect();
        return [...document.querySelectorAll(".compass .tick-label")].map((el) => {
          const b = el.getBoundingClientRect();
          return { text: el.textContent, inside: b.left >= tape.left && b.right <= tape.right };
        });
      });
    const whole = /^(N|NE|E|SE|S|SW|W|NW|\d{2,3})$/;
    const beforeGrant = await messageCount(page);
    await takeHelm(page);
    await messageShown(page, "thrusters are neutral", beforeGrant);
    // heading 300 (the thesis' complaint: "00" for 300 at the left edge) and around the dial
    const cdp = await context.newCDPSession(page);
    const right = await page.locator("#stick-right").boundingBox();
    const cx = right.x + right.width / 2;
    const cy = right.y + right.height / 2;
    await cdp.send("Input.dispatchTouchEvent", { type: "touchStart", touchPoints: [{ x: cx, y: cy, id: 1 }] });
    await cdp.send("Input.dispatchTouchEvent", { type: "touchMove", touchPoints: [{ x: cx + right.width * 0.45, y: cy, id: 1 }] });
    // driving: the grant's "thrusters are neutral" message goes
    await until(() => page.locator("#message").textContent(), (t) => !/thrusters are neutral/.test(t ?? ""), WAIT_MS, "the grant message gone while driving");
    const seen = new Set();
    // (as long as the turn takes: the simulation keeps pace with the clock, and a busy
    // machine gives it less of it)
    const deadline = Date.now() + 3 * WAIT_MS;
    while (seen.size < 24 && Date.now() < deadline) {
      for (const l of await labels()) {
        assert.ok(l.inside, `compass label "${l.text}" sticks out of the tape`);
        assert.match(l.text, whole, `compass label "${l.text}" is cut`);
        seen.add(l.text);
      }
      await page.waitForTimeout(50);
    }
    await cdp.send("Input.dispatchTouchEvent", { type: "touchEnd", touchPoints: [] });
    assert.ok(seen.size >= 8, `the vehicle turned too little to check the tape: ${[...seen]}`);
    await screenshot(page, "operator-tablet-hud-1024x768.png", { fullPage: false });
    await page.locator("#release-control").click();
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

test("gamepad: table 7.2 through a stubbed navigator.getGamepads; the keyboard is ignored in gamepad mode", { timeout: TEST_MS }, async () => {
  const { context, page } = await operator({ ...DESKTOP, name: "e2e-gamepad", init: stubPad });
  const setPad = (axes) => page.evaluate((a) => (window.__pad.axes = a), axes);
  try {
    await page.locator("#input-gamepad").click();
    await page.locator('[data-testid="gamepad-status"]', { hasText: "Stub pad" }).waitFor();
    await takeHelm(page);
    // The grant forgot every input: the pad counts again once the page has read it at rest,
    // on an animation frame after the grant (a stick held through a grant stays neutral).
    await afterFrames(page);
    // right stick 55 % up: surge (0.55 − 0.1) / 0.9 = 0.5 after the default deadband
    await setPad([0, 0, 0, -0.55]);
    await until(() => num(page, "#cmd-surge"), (v) => Math.abs(v - 0.5) < 0.011, WAIT_MS, "surge 0.50 from the right stick");
    // a stop with the stick held: neutral, and the pad disarmed until it is centred
    await page.locator("#stop").click();
    await page.locator('[data-testid="gamepad-status"]', { hasText: "centre the sticks to arm" }).waitFor();
    await until(() => num(page, "#cmd-surge"), (v) => v === 0, WAIT_MS, "neutral after the stop with the stick held");
    await afterFrames(page);
    assert.equal(await num(page, "#cmd-surge"), 0, "a stick held through a stop moved the vehicle");
    await setPad([0, 0, 0, 0]);
    await page.locator('[data-testid="gamepad-status"]', { hasText: "centre the sticks" }).waitFor({ state: "detached" });
    await setPad([0, 0, 0, -0.55]);
    await until(() => num(page, "#cmd-surge"), (v) => Math.abs(v - 0.5) < 0.011, WAIT_MS, "surge 0.50 again once centred");
    // right stick X: yaw; left stick Y down: heave
    await setPad([0, 1, 0.55, -0.55]);
    await until(
      async () => [await num(page, "#cmd-yaw"), await num(page, "#cmd-heave")],
      ([y, h]) => Math.abs(y - 0.5) < 0.011 && h === 1,
      WAIT_MS,
      "yaw 0.50 and heave 1",
    );
    // keys are input of another mode: ignored
    await hold(page, "KeyS", 300);
    assert.ok(Math.abs((await num(page, "#cmd-surge")) - 0.5) < 0.011, "a key changed the command in gamepad mode");
    // inside the deadband: neutral
    await setPad([0, 0.05, 0.08, -0.09]);
    await until(() => thrusterValues(page), allZero, WAIT_MS, "neutral inside the deadband");
    await page.locator("#release-control").click();
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

const storedMapping = (page) =>
  page.evaluate(async () => {
    // all of them: a missing key's 404 would be reported in the console
    const r = await fetch("/api/settings", { cache: "no-store" });
    return (await r.json()).settings["gamepad.mapping"] ?? "none";
  });

test("gamepad buttons: one command per press, the mapping editor assigns by pressing, kept on the server per user", { timeout: TEST_MS }, async () => {
  const { context, page } = await operator({ ...DESKTOP, name: "e2e-buttons", init: stubPad });
  try {
    // a known start: this server's local user has the default mapping
    await page.evaluate(() => fetch("/api/settings/gamepad.mapping", { method: "DELETE" }));
    await page.reload();
    await page.locator('#status[data-state="connected"]').waitFor();

    // Home: the gamepad becomes the input (a safe switch); Start: request control
    await page.locator("#input-keyboard").click();
    await until(() => helmState(page), (h) => h.state === "free", WAIT_MS, "a free helm");
    await pressButton(page, 16);
    await page.locator('#input-gamepad[aria-checked="true"]').waitFor();
    await page.locator('[data-testid="mapping-status"][data-state="default"]').waitFor({ state: "attached" });
    await pressButton(page, 9);
    await page.locator('#helm-state[data-me="pilot"]').waitFor();

    // D-pad right: lights up one step, once per press
    const lights = () => page.locator('[data-testid="lights-current"]').textContent();
    await until(lights, (t) => t === "0", WAIT_MS, "lights off at the start");
    await pressButton(page, 15);
    await until(lights, (t) => t === "32", WAIT_MS, "lights one step up");
    // Y held for a second: lights on/off acts once (an edge, not a level)
    await pressButton(page, 3, 1000);
    await until(lights, (t) => t === "0", WAIT_MS, "lights toggled off");
    await page.waitForTimeout(300);
    assert.equal(await lights(), "0", "a held toggle acted more than once");
    await pressButton(page, 3);
    await until(lights, (t) => t === "32", WAIT_MS, "lights back on at their last brightness");
    await pressButton(page, 14);
    await until(lights, (t) => t === "0", WAIT_MS, "lights one step down");

    // the editor: Assign "Stop", press A → A stops; the mapping goes to the server
    await page.locator("#button-map > summary").click();
    assert.equal(await page.locator("#map-stop").textContent(), "B");
    const banners = () => page.locator('[data-testid="stop-banner"]').count();
    await until(banners, (n) => n === 0, 8000, "no recent stop shown");
    await page.locator("#assign-stop").click();
    await page.locator("#map-stop", { hasText: "press a button" }).waitFor();
    await pressButton(page, 0);
    await page.locator("#map-stop", { hasText: "A" }).waitFor();
    assert.equal(await page.locator("#map-depth_hold").textContent(), "—", "A kept its old action");
    await page.locator('[data-testid="mapping-status"][data-state="saved"]').waitFor({ state: "attached" });
    const stored = await storedMapping(page);
    assert.equal(stored.actions.stop, 0);
    assert.equal(stored.actions.depth_hold, undefined);
    assert.equal(stored.version, 1);

    // assigning did not run the action; pressing A now stops the vehicle
    assert.equal(await banners(), 0, "assigning a button ran its action");
    await pressButton(page, 0);
    await page.locator('[data-testid="stop-banner"]').waitFor();
    await page.locator('[data-testid="gamepad-last"]', { hasText: "A → Stop" }).waitFor();

    // the mapping follows the user to another device (a fresh browser context)
    const other = await operator({ ...TABLET, name: "e2e-buttons-2", init: stubPad, touch: true });
    try {
      await other.page.locator("#input-gamepad").click();
      await other.page.locator('[data-testid="mapping-status"][data-state="stored"]').waitFor({ state: "attached" });
      await other.page.locator("#button-map > summary").click();
      assert.equal(await other.page.locator("#map-stop").textContent(), "A");
    } finally {
      await other.context.close();
    }

    // reset to default: B stops again, the server keeps nothing
    await page.locator("#mapping-reset").click();
    await page.locator('[data-testid="mapping-status"][data-state="default"]').waitFor({ state: "attached" });
    assert.equal(await page.locator("#map-stop").textContent(), "B");
    assert.equal(await storedMapping(page), "none");

    // Back: release control
    await pressButton(page, 8);
    await page.locator('#helm-state[data-me="watching"]').waitFor();
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

test("settings: values go to the server and its reason is shown in the form; camera rotation is the vehicle's, on every page", { timeout: TEST_MS }, async () => {
  const { context, page } = await operator({ ...DESKTOP, name: "e2e-settings" });
  try {
    // observers' controls are disabled
    assert.equal(await page.locator("#gain-set").isDisabled(), true);
    await takeHelm(page);
    const result = async (field) => {
      const el = page.locator(`[data-testid="${field}-status"]`);
      await until(async () => await el.getAttribute("data-state"), (s) => s === "ok" || s === "error", WAIT_MS, `${field} answered`);
      return { state: await el.getAttribute("data-state"), text: ((await el.textContent()) ?? "").trim() };
    };
    // out of range: refused, with the server's reason next to the field
    await page.locator("#gain-input").fill("2");
    await page.locator("#gain-set").click();
    const bad = await result("gain");
    assert.equal(bad.state, "error", "gain 2 must be refused");
    assert.ok(bad.text.length > 3 && !/timeout|not connected/.test(bad.text), `gain reason: "${bad.text}"`);
    console.log(`# gain 2 → ${bad.text}`);
    // a control mode change: the server's answer (✓, or its reason where the feature is missing)
    await page.locator("#control-mode-manual").click();
    const mode = await result("control_mode");
    console.log(`# set_control_mode manual → ${mode.state} ${mode.text}`);
    if (mode.state === "ok") {
      // manual column of table 7.1: Q drives the port thruster alone, absolute values
      await page.locator('#control-mode-manual[aria-checked="true"]').waitFor();
      await page.locator("#input-keyboard").click();
      await page.keyboard.down("KeyQ");
      try {
        const t = await until(() => thrusterValues(page), (v) => v.port > 0, WAIT_MS, "port thruster from Q in manual mode");
        assert.equal(t.vertical, 0);
        assert.equal(t.starboard, 0);
      } finally {
        await page.keyboard.up("KeyQ");
      }
      await until(() => thrusterValues(page), allZero, WAIT_MS, "neutral after releasing Q");
      await page.locator("#control-mode-motion").click();
      await page.locator('#control-mode-motion[aria-checked="true"]').waitFor();
      // a valid gain is taken and shown
      await page.locator("#gain-input").fill("0.6");
      await page.locator("#gain-set").click();
      await page.locator('[data-testid="gain-current"]', { hasText: "0.60" }).waitFor();
      await page.locator("#gain-input").fill("0.5");
      await page.locator("#gain-set").click();
      await page.locator('[data-testid="gain-current"]', { hasText: "0.50" }).waitFor();
    } else {
      assert.ok(mode.text.length > 3, "an error without a reason");
    }
    await page.locator("#depth-input").fill("1.5");
    await page.locator("#depth-set").click();
    const depth = await result("depth");
    console.log(`# autopilot depth 1.5 → ${depth.state} ${depth.text}`);
    if (depth.state === "ok") await page.locator("#depth-off").click();

    // image rotation: a vehicle setting, stored on the server and applied on every page
    const watcher = await operator({ ...TABLET, name: "e2e-settings-watch" });
    try {
      assert.equal(await watcher.page.locator("#rotation").isDisabled(), true, "observers do not turn the vehicle's camera");
      await page.locator("#rotation").selectOption("180");
      await page.locator('[data-testid="camera"][data-rotation="180"]').waitFor();
      await watcher.page.locator('[data-testid="camera"][data-rotation="180"]').waitFor();
      await page.locator("#release-control").click();
      await page.reload();
      await page.locator('[data-testid="camera"][data-rotation="180"]').waitFor();
      await takeHelm(page);
      await page.locator("#rotation").selectOption("0");
      await watcher.page.locator('[data-testid="camera"][data-rotation="0"]').waitFor();
    } finally {
      await watcher.context.close();
    }
    assertNoPageProblems();
  } finally {
    await context.close();
  }
});

test("camera: the vehicle's MJPEG camera plays over the video socket and fills the camera area; a vehicle without one says so", { timeout: TEST_MS }, async () => {
  const id = process.env.E2E_CAMERA_VEHICLE;
  assert.ok(id, "E2E_CAMERA_VEHICLE names a vehicle with a camera (set by external_test.exs)");
  // the video socket goes through a route the test can cut (then it passes on to the server)
  let cut = false;
  const viewer = await open(browser, { ...TABLET, name: "e2e-cam", path: `/?vehicle=${encodeURIComponent(id)}&name=e2e-cam` });
  try {
    const { page } = viewer;
    await page.routeWebSocket(/\/video\//, (ws) => {
      if (cut) ws.close({ code: 1011, reason: "cut by the test" });
      else ws.connectToServer();
    });
    await page.reload();
    // JPEG frames drawn on the canvas: the fixture images are 160×120
    const feed = page.locator('[data-testid="camera"][data-camera="on"] [data-testid="video-feed"][data-path="jpeg"][data-showing="true"]');
    await feed.waitFor();
    await until(() => page.locator(".video-picture").evaluate((c) => c.width), (w) => w === 160, WAIT_MS, "a decoded camera frame");
    const box = await page.locator(".video-picture").boundingBox();
    const area = await page.locator('[data-testid="camera"]').boundingBox();
    assert.ok(box && area && box.width >= area.width - 2, "the picture does not fill the camera area's width");
    // the line under it and the HUD: MJPEG, its size, frames and the latency
    await until(() => page.locator('[data-testid="video-health"]').textContent(), (t) => /MJPEG 160×120/.test(t ?? "") && /latency \d+ ms/.test(t ?? ""), WAIT_MS, "the health line");
    await until(() => page.locator('[data-testid="hud-video-latency"]').textContent(), (t) => /video \d+ ms/.test(t ?? ""), WAIT_MS, "the video latency in the HUD");
    // the HUD says the camera runs (frame rate) and that this test server does not record
    await until(() => page.locator('[data-testid="hud-camera"]').textContent(), (t) => /cam \d+ fps/.test(t ?? ""), WAIT_MS, "camera fps in the HUD");
    assert.equal(await page.locator('[data-testid="hud-recording"]').getAttribute("data-state"), "off");
    await screenshot(page, "operator-camera-1024x768.png", { fullPage: false });

    // a broken stream is said over the picture and the socket opened again until it is back
    cut = true;
    await page.reload();
    await page.locator('[data-testid="video-waiting"]', { hasText: /interrupted|refused|unreachable/ }).waitFor();
    cut = false;
    await page.waitForFunction(() => window.neptunusVideo.displayed > 0, null, { timeout: 15_000 });
    await page.locator('[data-testid="video-waiting"]').waitFor({ state: "detached" });
    assertNoPageProblems();

    const none = process.env.E2E_NO_CAMERA_VEHICLE;
    assert.ok(none, "E2E_NO_CAMERA_VEHICLE names a vehicle without a camera (set by external_test.exs)");
    await page.goto(`${BASE}/?vehicle=${encodeURIComponent(none)}&name=e2e-cam`);
    await waitTelemetry(page); // joined: the server has said what camera it has
    await page.locator('[data-testid="no-camera"]').waitFor();
    assert.equal(await page.locator('[data-testid="video-health"]').count(), 0, "no health line without a camera");
    assertNoPageProblems();
  } finally {
    await viewer.context.close();
  }
});

