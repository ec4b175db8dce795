// Browser test of the replay page (/replay.html) against a running Neptunus server whose
// recordings hold one dive of neptunus-1 with H.264 video (external_test.exs writes it):
// E2E_DIVE its name, E2E_FRAMES_US its frames' times (µs, comma-separated), E2E_EVENTS_MS
// the times of its helm, stop, autopilot and snapshot entries. See helpers.mjs for the set-up.

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import { DESKTOP, TABLET, TEST_MS, WAIT_MS, assertNoPageProblems, launch, open, screenshot, until } from "./helpers.mjs";

const DIVE = process.env.E2E_DIVE;
const FRAMES_US = (process.env.E2E_FRAMES_US ?? "").split(",").map(Number);
const EVENTS_MS = (process.env.E2E_EVENTS_MS ?? "").split(",").map(Number);
const FRAME_MS = (FRAMES_US[1] - FRAMES_US[0]) / 1000;

let browser;

before(async () => {
  assert.ok(DIVE && FRAMES_US.length > 10 && EVENTS_MS.length === 4, "E2E_DIVE, E2E_FRAMES_US and E2E_EVENTS_MS must be set");
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

/** The replay page with the dive picked (by a click, or a tap on a tablet), its first picture drawn. */
async function openDive(size, name, touch = false) {
  const opened = await open(browser, { ...size, name, touch, path: "/replay.html?vehicle=neptunus-1", ready: '[data-testid="replay-page"][data-ready="true"]' });
  const { page } = opened;
  const sockets = [];
  page.on("websocket", (ws) => sockets.push(ws.url()));
  const dive = page.locator(`[data-testid="replay-dive"][data-name="${DIVE}"]`);
  if (touch) await dive.tap();
  else await dive.click();
  await page.locator('[data-testid="replay-video"][data-frame-index]').waitFor();
  return { ...opened, sockets };
}

/** The index of the last frame at or before `ms`. */
function frameAt(ms) {
  let found = -1;
  for (let i = 0; i < FRAMES_US.length; i++) if (FRAMES_US[i] <= ms * 1000) found = i;
  return found;
}

/** The frame the picture shows at `ms`: the one at or before it, the first before the first. */
const pictureAt = (ms) => Math.max(0, frameAt(ms));

/**
 * What the page shows now: the picture's frame index, the plots' cursor (ms), and its own
 * signals (sync.ts): `holds` position changes begun (seeks, steps, pauses), `settled` the
 * last one whose picture is shown, `stale` while the picture is not yet the one at the cursor.
 */
async function shown(page) {
  return page.evaluate(() => {
    const player = document.querySelector('[data-testid="replay-player"]');
    return {
      frame: Number(document.querySelector('[data-testid="replay-video"]')?.getAttribute("data-frame-index")),
      cursor: Number(document.querySelector('[data-testid="replay-plot-cursor"]')?.getAttribute("data-ms")),
      playing: player?.getAttribute("data-playing"),
      rate: player?.getAttribute("data-rate"),
      holds: Number(player?.getAttribute("data-holds")),
      settled: Number(player?.getAttribute("data-settled")),
      stale: player?.getAttribute("data-stale"),
    };
  });
}

/**
 * Does `act` (a seek, a step, a pause: `n` position changes) and waits for the page to say
 * their picture is shown: `n` more holds than before, all settled. What the page shows then.
 */
async function settled(page, act, what, n = 1) {
  const before = await shown(page);
  await act();
  return until(
    () => shown(page),
    (s) => s.holds >= before.holds + n && s.settled === s.holds && s.stale === "false",
    WAIT_MS,
    `${what}: the picture at the cursor shown`,
  );
}

/**
 * Every animation frame for `ms`: how many frames the picture is from the one at the plots'
 * cursor (the picture's index minus the cursor's), or null while the page marks the picture
 * stale (a seek's frame being decoded).
 */
async function sampleSync(page, ms) {
  const samples = await page.evaluate(
    ({ ms, framesUs }) =>
      new Promise((resolve) => {
        const out = [];
        const end = performance.now() + ms;
        const at = (t) => {
          let found = -1;
          for (let i = 0; i < framesUs.length; i++) if (framesUs[i] <= t * 1000) found = i;
          return found;
        };
        const step = () => {
          const frame = Number(document.querySelector('[data-testid="replay-video"]')?.getAttribute("data-frame-index"));
          const cursor = Number(document.querySelector('[data-testid="replay-plot-cursor"]')?.getAttribute("data-ms"));
          const stale = document.querySelector('[data-testid="replay-player"]')?.getAttribute("data-stale") === "true";
          out.push(stale ? null : frame - at(cursor));
          if (performance.now() < end) requestAnimationFrame(step);
          else resolve(out);
        };
        requestAnimationFrame(step);
      }),
    { ms, framesUs: FRAMES_US },
  );
  assert.ok(samples.length > 5, `only ${samples.length} animation frames sampled`);
  return samples;
}

/** The share of samples within one frame, the share marked stale, the largest distance left unmarked. */
function syncFigures(samples) {
  const unmarked = samples.filter((d) => d !== null);
  const share = (n) => Number((n / samples.length).toFixed(3));
  return {
    within: share(unmarked.filter((d) => Math.abs(d) <= 1).length),
    stale: share(samples.length - unmarked.length),
    worst: unmarked.length > 0 ? Math.max(...unmarked.map(Math.abs)) : null,
    n: samples.length,
  };
}

test("replay: the dive listed with its summary; picked, its picture and HUD; it never opens a socket to the vehicle", { timeout: TEST_MS }, async () => {
  const { context, page, sockets } = await openDive(DESKTOP, "e2e-replay-desktop");
  try {
    const summary = await page.locator(`[data-testid="replay-dive"][data-name="${DIVE}"]`).textContent();
    assert.match(summary, /max 3\.0 m/);
    assert.match(summary, /ada/);
    assert.match(summary, /1 stops/);
    assert.match(summary, /1 snapshots/);
    assert.match(summary, /video h264/);
    const s = await shown(page);
    assert.equal(s.frame, 0);
    assert.equal(s.playing, "false");
    assert.match((await page.locator('[data-testid="replay-depth"]').textContent()) ?? "", /^\d+\.\d\d$/);
    // the events one jumps between
    const events = await page.locator('[data-testid="replay-events"] button').allTextContents();
    assert.deepEqual(
      events.map((e) => e.replace(/^\S+ /, "")),
      ["helm: ada", "stop: deadman", "autopilot: depth hold 2 m", "snapshot x.jpg"],
    );
    // its exports, downloaded as the page offers them (the server makes them)
    const exports = await page.locator('[data-testid="replay-exports"] a').evaluateAll((as) => as.map((a) => [a.dataset.format, a.getAttribute("href")]));
    assert.deepEqual(exports.map(([f]) => f), ["mp4", "mcap", "csv", "ass", "jsonl"]);
    for (const [format, href] of exports) {
      const response = await page.request.get(new URL(href, page.url()).href);
      assert.equal(response.status(), 200, `${format} export: HTTP ${response.status()}`);
      assert.match(response.headers()["content-disposition"] ?? "", new RegExp(`attachment; filename=".+\\.${format}"`));
      assert.ok((await response.body()).length > 0, `${format} export is empty`);
    }
    // its title and notes, edited here (local mode: anyone may); typing them plays nothing
    const before = await shown(page);
    await page.locator('[data-testid="replay-title"]').fill("Hull inspection, pier 4");
    await page.locator('[data-testid="replay-notes-text"]').click();
    await page.keyboard.type("kept: two anodes worn\nnext: change them");
    await page.locator('[data-testid="replay-notes-save"]').click();
    await page.locator('[data-testid="replay-notes-status"]', { hasText: "Saved." }).waitFor();
    const typed = await shown(page);
    assert.deepEqual([typed.playing, typed.holds], ["false", before.holds], "keys typed in the notes played or sought");
    assert.match((await page.locator(`[data-testid="replay-dive"][data-name="${DIVE}"]`).textContent()) ?? "", /^Hull inspection, pier 4/);
    assert.ok(await page.locator('[data-testid="replay-notes-save"]').isDisabled(), "nothing left to save");
    await screenshot(page, "replay-desktop.png");
    // saved on the server: a new page shows them
    await page.reload();
    await page.locator(`[data-testid="replay-dive"][data-name="${DIVE}"]`).click();
    assert.equal(await page.locator('[data-testid="replay-title"]').inputValue(), "Hull inspection, pier 4");
    assert.equal(await page.locator('[data-testid="replay-notes-text"]').inputValue(), "kept: two anodes worn\nnext: change them");
    assert.deepEqual(sockets, [], "the replay page opened a WebSocket");
  } finally {
    await context.close();
  }
  assertNoPageProblems();
});

test("replay: the picture and the plots' cursor stay within one frame while seeking and at 4×", { timeout: TEST_MS }, async () => {
  const { context, page } = await openDive(DESKTOP, "e2e-replay-sync");
  try {
    const seekBar = page.locator('[data-testid="replay-seek"]');
    const start = FRAMES_US[0] / 1000;
    // seeking while paused: once the page says the seek's picture is shown, it is exactly the
    // frame at the cursor, and the cursor is where the seek put it
    for (const i of [40, 7, 75, 16, 0]) {
      const to = Math.round(FRAMES_US[i] / 1000 + 1);
      assert.equal(frameAt(to), i);
      const s = await settled(page, () => seekBar.fill(String(to)), `a seek to frame ${i}`);
      assert.equal(s.cursor, to);
      assert.equal(s.frame, i);
    }
    // playing at 4×, sampled every animation frame
    await page.locator('[data-testid="replay-rate-4"]').click();
    await settled(page, () => seekBar.fill(String(Math.round(start))), "a seek to the start");
    await page.locator('[data-testid="replay-play"]').click();
    const playingSamples = await sampleSync(page, 1_200);
    // and around a seek while it plays: the cursor holds at the position sought until its
    // picture is shown (the picture marked stale meanwhile), then both go on together
    const to = Math.round(FRAMES_US[20] / 1000);
    const before = await shown(page);
    const [seekingSamples] = await Promise.all([sampleSync(page, 600), seekBar.fill(String(to))]);
    const playing = syncFigures(playingSamples);
    const seeking = syncFigures(seekingSamples);
    console.log(`# sync at 4×: ${JSON.stringify(playing)}; around a seek while playing: ${JSON.stringify(seeking)} (frame ${FRAME_MS.toFixed(1)} ms)`);
    // How long a seek's picture takes, and so how many samples are marked stale, depends on the
    // CPU the browser gets: printed above. What the page promises is judged: the cursor is never
    // more than one frame from the picture unless the picture is marked stale.
    for (const [name, samples] of [["playing", playingSamples], ["around the seek", seekingSamples]]) {
      const off = samples.filter((d) => d !== null && Math.abs(d) > 1);
      assert.deepEqual(off, [], `${name}: the picture more than one frame from the cursor, not marked stale`);
    }
    // the seek while playing settles: its picture shown, the clock on from the position sought
    const after = await until(
      () => shown(page),
      (s) => s.holds > before.holds && s.settled === s.holds && s.stale === "false",
      WAIT_MS,
      "the seek while playing settled",
    );
    assert.ok(after.cursor >= to, `the clock went on from before the position sought: ${JSON.stringify(after)}`);
    assert.ok(Math.abs(after.frame - frameAt(after.cursor)) <= 1, `after the seek: ${JSON.stringify(after)}`);
    assert.equal(after.rate, "4");
    // paused (by the button, or at the dive's end, which holds there): exactly the frame at the cursor
    const paused =
      (await shown(page)).playing === "true"
        ? await settled(page, () => page.locator('[data-testid="replay-play"]').click(), "a pause")
        : await until(() => shown(page), (p) => p.settled === p.holds && p.stale === "false", WAIT_MS, "paused at the end, its picture shown");
    assert.equal(paused.playing, "false");
    assert.equal(paused.frame, pictureAt(paused.cursor), `paused: ${JSON.stringify(paused)}`);
  } finally {
    await context.close();
  }
  assertNoPageProblems();
});

test("replay: frame steps, previous/next event and the keyboard shortcuts", { timeout: TEST_MS }, async () => {
  const { context, page } = await openDive(DESKTOP, "e2e-replay-keys");
  try {
    const seekBar = page.locator('[data-testid="replay-seek"]');
    /** paused: the picture is exactly the frame at the cursor */
    const exact = (s, what) => assert.equal(s.frame, pictureAt(s.cursor), `${what}: ${JSON.stringify(s)}`);
    let s = await settled(page, () => seekBar.fill(String(Math.round(FRAMES_US[30] / 1000))), "a seek to frame 30");
    assert.equal(s.frame, 30);
    s = await settled(page, () => page.locator('[data-testid="replay-frame-forward"]').click(), "one frame on");
    assert.deepEqual([s.frame, s.cursor], [31, FRAMES_US[31] / 1000]);
    s = await settled(page, () => page.keyboard.press(",").then(() => page.keyboard.press(",")), "two frames back", 2);
    assert.deepEqual([s.frame, s.cursor], [29, FRAMES_US[29] / 1000]);
    s = await settled(page, () => page.keyboard.press("."), "one frame on by key");
    assert.deepEqual([s.frame, s.cursor], [30, FRAMES_US[30] / 1000]);
    s = await settled(page, () => page.locator('[data-testid="replay-frame-back"]').click(), "one frame back");
    assert.deepEqual([s.frame, s.cursor], [29, FRAMES_US[29] / 1000]);

    // next event: the helm handover, then the stop; previous: back to the handover
    await settled(page, () => seekBar.fill(String(Math.round(FRAMES_US[0] / 1000))), "a seek to the first frame");
    s = await settled(page, () => page.locator('[data-testid="replay-next-event"]').click(), "next event");
    assert.equal(s.cursor, EVENTS_MS[0]);
    exact(s, "at the handover");
    s = await settled(page, () => page.keyboard.press("n"), "next event by key");
    assert.equal(s.cursor, EVENTS_MS[1]);
    exact(s, "at the stop");
    assert.equal(await page.locator('[data-testid="replay-current-event"]').textContent(), "stop: deadman");
    s = await settled(page, () => page.keyboard.press("p"), "previous event by key");
    assert.equal(s.cursor, EVENTS_MS[0]);
    exact(s, "back at the handover");
    // ← → and Home / End seek, each to its picture
    s = await settled(page, () => page.keyboard.press("ArrowRight"), "5 s on");
    assert.equal(s.cursor, EVENTS_MS[0] + 5_000);
    exact(s, "5 s on");
    s = await settled(page, () => page.keyboard.press("Home"), "the dive's start");
    assert.equal(s.cursor, Number(await seekBar.getAttribute("min")));
    exact(s, "the start");
    s = await settled(page, () => page.keyboard.press("End"), "the dive's end");
    assert.equal(s.cursor, Number(await seekBar.getAttribute("max")));
    exact(s, "the end");
    s = await settled(page, () => page.keyboard.press("p"), "previous event from the end");
    assert.equal(s.cursor, EVENTS_MS[3]);

    // space plays and pauses; > and < change the rate
    await page.keyboard.press(" ");
    await until(() => shown(page), (p) => p.playing === "true", WAIT_MS, "playing");
    await page.keyboard.press(">");
    await until(() => shown(page), (p) => p.rate === "2", WAIT_MS, "2×");
    await page.keyboard.press("<");
    await page.keyboard.press("<");
    await until(() => shown(page), (p) => p.rate === "0.5", WAIT_MS, "0.5×");
    const paused = await settled(page, () => page.keyboard.press("k"), "a pause by key");
    assert.equal(paused.playing, "false");
    exact(paused, "paused");
    // the cursor is drawn at the next animation frame; then it stays
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
    const still = await shown(page);
    await new Promise((r) => setTimeout(r, 300));
    assert.equal((await shown(page)).cursor, still.cursor, "the cursor moved while paused");
    assert.equal(still.cursor, paused.cursor, "the cursor moved after the pause settled");
  } finally {
    await context.close();
  }
  assertNoPageProblems();
});

test("replay on a 1024×768 tablet by touch: every control on screen, play by a tap", { timeout: TEST_MS }, async () => {
  const { context, page } = await openDive(TABLET, "e2e-replay-tablet", true);
  try {
    const width = await page.evaluate(() => document.scrollingElement?.scrollWidth ?? 0);
    assert.ok(width <= TABLET.width, `the page is ${width} px wide on a ${TABLET.width} px screen`);
    for (const id of ["replay-play", "replay-prev-event", "replay-next-event", "replay-frame-back", "replay-frame-forward", "replay-rate-4", "replay-seek"]) {
      const box = await page.locator(`[data-testid="${id}"]`).boundingBox();
      assert.ok(box && box.x >= 0 && box.x + box.width <= TABLET.width, `${id} is off screen: ${JSON.stringify(box)}`);
      assert.ok(box.height >= 36, `${id} is too small to tap: ${box.height} px`);
    }
    await page.locator('[data-testid="replay-rate-4"]').tap();
    await page.locator('[data-testid="replay-play"]').tap();
    await until(() => shown(page), (s) => s.playing === "true", WAIT_MS, "playing after a tap");
    await until(() => shown(page), (s) => s.frame > 10, WAIT_MS, "the picture moving on");
    await page.locator('[data-testid="replay-play"]').tap();
    await until(() => shown(page), (s) => s.playing === "false", WAIT_MS, "paused after a tap");
    await screenshot(page, "replay-tablet.png");
  } finally {
    await context.close();
  }
  assertNoPageProblems();
});
