// Browser tests of the vehicle's video (issue #27, docs/API.md "Video"): headless Debian
// Chromium (playwright-core) against a running Neptunus server in local mode whose vehicle
// E2E_VIDEO_VEHICLE has the simulated camera (H.264, the render stamp in its corner),
// E2E_RESTART_VEHICLE a camera that ends every few seconds (the server restarts it) and
// E2E_BUSY_VEHICLE a heavy one (about 3 Mbit/s: a slow viewer's buffers fill within seconds);
// external_test.exs starts them (test/fixtures/camera/h264_camera.sh).
//
//   E2E_VIDEO_VEHICLE=rov E2E_RESTART_VEHICLE=rov2 E2E_BUSY_VEHICLE=rov3 \
//     NEPTUNUS_URL=http://127.0.0.1:4102 node --test test/e2e/video.e2e.mjs
//
// Every wait is on an event the page counts (window.neptunusVideo, src/video/player.ts):
// pictures decoded and shown, keyframes, generations; never on time passing.

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import { BASE, DESKTOP, TABLET, TEST_MS, WAIT_MS, assertNoPageProblems, launch, open, pressButton, screenshot, stubPad, takeHelm, until, waitTelemetry } from "./helpers.mjs";

const VEHICLE = process.env.E2E_VIDEO_VEHICLE;
const RESTART_VEHICLE = process.env.E2E_RESTART_VEHICLE;
const BUSY_VEHICLE = process.env.E2E_BUSY_VEHICLE;
/** the camera's first pictures take a while on a busy machine (renderer, ffmpeg, decoder) */
const VIDEO_MS = 20_000;
/** the video pages' own timeouts: a page that decodes video loads slower on a busy machine */
const PAGE_MS = 15_000;

let browser;

before(async () => {
  assert.ok(VEHICLE, "E2E_VIDEO_VEHICLE names a vehicle with the sim camera (set by external_test.exs)");
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

const counters = (page) => page.evaluate(() => (window.neptunusVideo ? { ...window.neptunusVideo, samples: window.neptunusVideo.samples.length } : null));

/** Waits until the page's video counters satisfy `pred` (evaluated in the page). */
async function waitVideo(page, pred, arg, what, ms = VIDEO_MS) {
  try {
    await page.waitForFunction(pred, arg, { timeout: ms, polling: 100 });
  } catch (err) {
    throw new Error(`timed out after ${ms} ms waiting for ${what}; counters: ${JSON.stringify(await counters(page))}`, { cause: err });
  }
}

async function videoPage(opts) {
  const side = await open(browser, { ...DESKTOP, wait: PAGE_MS, ...opts, path: `/?vehicle=${encodeURIComponent(opts.vehicle ?? VEHICLE)}&name=${encodeURIComponent(opts.name)}${opts.video ? `&video=${opts.video}` : ""}` });
  return side;
}

/**
 * The picture as the page shows it (canvas or video), below the stamp's band, as the mean
 * luma of 16×16 blocks: the scene's large shapes, without the marine snow's specks and the
 * encoder's noise.
 */
function grab(page) {
  return page.evaluate(() => {
    const el = document.querySelector('[data-testid="video-feed"] .video-picture');
    if (!el) return null;
    const w = el instanceof HTMLVideoElement ? el.videoWidth : el.width;
    const h = (el instanceof HTMLVideoElement ? el.videoHeight : el.height) - 16;
    const c = document.createElement("canvas");
    c.width = w;
    c.height = h + 16;
    const ctx = c.getContext("2d");
    ctx.drawImage(el, 0, 0);
    const data = ctx.getImageData(0, 16, w, h).data;
    const B = 16;
    const blocks = [];
    for (let by = 0; by + B <= h; by += B) {
      for (let bx = 0; bx + B <= w; bx += B) {
        let sum = 0;
        for (let y = by; y < by + B; y++) {
          for (let x = bx; x < bx + B; x++) {
            const i = (y * w + x) * 4;
            sum += 0.299 * data[i] + 0.587 * data[i + 1] + 0.114 * data[i + 2];
          }
        }
        blocks.push(sum / (B * B));
      }
    }
    return { w, h, blocks };
  });
}

/** The width of the picture shown (canvas or video). */
function pictureWidth(page) {
  return page.locator('[data-testid="video-feed"] .video-picture').evaluate((el) => (el instanceof HTMLVideoElement ? el.videoWidth : el.width));
}

/** Mean absolute difference of two grabs' blocks (0..255). */
function difference(a, b) {
  assert.equal(a.blocks.length, b.blocks.length, "pictures of different sizes");
  let sum = 0;
  for (let i = 0; i < a.blocks.length; i++) sum += Math.abs(a.blocks[i] - b.blocks[i]);
  return sum / a.blocks.length;
}

for (const path of ["webcodecs", "mse"]) {
  test(`H.264 decoded with ${path} (forced): pictures, the stamp read, the health line and the HUD latency`, { timeout: TEST_MS }, async () => {
    const { context, page } = await videoPage({ name: `e2e-video-${path}`, video: path });
    try {
      await waitVideo(page, (p) => window.neptunusVideo?.path === p && window.neptunusVideo.displayed >= 30 && window.neptunusVideo.stamps >= 30, path, `30 pictures shown with ${path}, stamps read`);
      const c = await counters(page);
      assert.equal(c.path, path);
      assert.equal(c.errors, 0, `decoder errors: ${c.lastError}`);
      assert.equal(c.firstReceived.keyframe, true, "the first frame a page gets is a keyframe");
      // the page and the server share this machine's clock, so the page's estimate of the
      // server's clock is off by its offset exactly (up to half a round trip on a busy machine):
      // the latency it computes is that much off, and no more
      const offsetError = Math.abs(c.offsetMs ?? 0);
      assert.ok(
        c.renderToDisplay > -offsetError - 1 && c.renderToDisplay < 5000,
        `render→display ${c.renderToDisplay} ms (the page's clock offset ${c.offsetMs} ms)`,
      );
      assert.ok(c.serverToDisplay !== null, "server→display known (the page has the server's clock)");
      // the line under the picture: codec and size, frames, latency (both kinds), the path
      const line = page.locator('[data-testid="video-health"]');
      await until(() => line.textContent(), (t) => /H\.264 640×360/.test(t) && /\d+ fps/.test(t) && /latency \d+ ms/.test(t) && /render→display \d+ ms/.test(t), WAIT_MS, "the health line's figures");
      assert.equal(await page.locator('[data-testid="video-feed"]').getAttribute("data-path"), path);
      await until(() => page.locator('[data-testid="hud-video-latency"]').textContent(), (t) => /video \d+ ms/.test(t ?? ""), WAIT_MS, "the latency in the HUD");
      assert.equal(await page.locator('[data-testid="video-waiting"]').count(), 0, "nothing said over a live picture");
      await screenshot(page, `video-${path}-1920x1080.png`, { fullPage: false });
    } finally {
      await context.close();
    }
    assertNoPageProblems();
  });
}

test("the camera page: the picture fills the window, with its health line and latency", { timeout: TEST_MS }, async () => {
  const { context, page } = await open(browser, { ...TABLET, name: "e2e-camera-page", path: `/camera.html?vehicle=${encodeURIComponent(VEHICLE)}`, wait: PAGE_MS });
  try {
    await waitVideo(page, () => window.neptunusVideo?.displayed >= 10 && window.neptunusVideo.stamps >= 10, null, "pictures on the camera page");
    await until(() => page.locator('[data-testid="video-health"]').textContent(), (t) => /H\.264 640×360/.test(t ?? "") && /render→display \d+ ms/.test(t ?? ""), WAIT_MS, "the health line");
    await until(() => page.locator('[data-testid="hud-video-latency"]').textContent(), (t) => /video \d+ ms/.test(t ?? ""), WAIT_MS, "the latency in the header");
    // the picture's box takes the window's width and most of its height
    const box = await page.locator('[data-testid="video-feed"]').boundingBox();
    assert.ok(box && box.width >= TABLET.width - 4 && box.height >= TABLET.height * 0.6, `the picture's box: ${JSON.stringify(box)}`);
    await screenshot(page, "camera-page-1024x768.png", { fullPage: false });
  } finally {
    await context.close();
  }
  assertNoPageProblems();
});

test("the rotation setting turns the picture on both paths", { timeout: TEST_MS }, async () => {
  for (const path of ["webcodecs", "mse"]) {
    const { context, page } = await videoPage({ ...TABLET, name: `e2e-rotate-${path}`, video: path });
    try {
      await waitVideo(page, () => window.neptunusVideo?.displayed >= 5, null, "pictures");
      await takeHelm(page);
      await page.locator("#rotation").selectOption("180");
      await page.locator('[data-testid="camera"][data-rotation="180"]').waitFor();
      const transform = await page.locator('[data-testid="video-feed"]').evaluate((el) => getComputedStyle(el).transform);
      // rotate(180deg): matrix(-1, 0, 0, -1, 0, 0) give or take rounding
      assert.match(transform, /^matrix\(-1, [-0-9.e]+, [-0-9.e]+, -1, 0, 0\)$/, `the picture's transform: ${transform}`);
      await page.locator("#rotation").selectOption("0");
      await page.locator('[data-testid="camera"][data-rotation="0"]').waitFor();
      await page.locator("#release-control").click();
    } finally {
      await context.close();
    }
  }
  assertNoPageProblems();
});

test("the picture changes when the vehicle yaws", { timeout: 90_000 }, async () => {
  const { context, page } = await videoPage({ name: "e2e-video-yaw" });
  try {
    await waitTelemetry(page);
    await waitVideo(page, () => window.neptunusVideo?.displayed >= 10, null, "pictures");
    await takeHelm(page);
    // the picture when still: two grabs 30 pictures apart (only marine snow moves)
    const still1 = await grab(page);
    const n = (await counters(page)).displayed;
    await waitVideo(page, (k) => window.neptunusVideo.displayed >= k + 30, n, "30 more pictures");
    const still2 = await grab(page);
    const stillDiff = difference(still1, still2);
    // yaw right until the heading has turned 45°
    const heading = async () => Number.parseFloat((await page.locator("#heading").textContent()) ?? "");
    const h0 = await heading();
    await page.keyboard.down("KeyD");
    try {
      await until(heading, (h) => Math.abs(((h - h0 + 540) % 360) - 180) >= 45, 45_000, "the heading turned 45°");
    } finally {
      await page.keyboard.up("KeyD");
    }
    const m = (await counters(page)).displayed;
    await waitVideo(page, (k) => window.neptunusVideo.displayed >= k + 3, m, "pictures after the turn");
    const turned = await grab(page);
    const turnDiff = difference(still2, turned);
    console.log(`# picture difference (16-px blocks, mean |Δluma|): still ${stillDiff.toFixed(2)}, after a 45° turn ${turnDiff.toFixed(2)}`);
    assert.ok(turnDiff > 3 * Math.max(stillDiff, 0.1), `the picture after a 45° turn differs by ${turnDiff.toFixed(2)} (still: ${stillDiff.toFixed(2)})`);
    await page.locator("#release-control").click();
  } finally {
    await context.close();
  }
  assertNoPageProblems();
});

test("a late joiner starts at a keyframe", { timeout: TEST_MS }, async () => {
  const first = await videoPage({ name: "e2e-video-first" });
  try {
    await waitVideo(first.page, () => window.neptunusVideo?.displayed >= 45, null, "the first viewer's pictures (past a keyframe interval)");
    const late = await videoPage({ name: "e2e-video-late" });
    try {
      await waitVideo(late.page, () => window.neptunusVideo?.displayed >= 10, null, "the late joiner's pictures");
      const c = await counters(late.page);
      assert.equal(c.firstReceived.keyframe, true, `the late joiner's first frame (sequence ${c.firstReceived.sequence}) is a keyframe`);
      assert.ok(c.firstReceived.sequence > 1, "it joined mid-stream");
      assert.equal(c.firstDecoded, c.firstReceived.sequence, "the late joiner decoded from its very first frame on");
      assert.equal(c.errors, 0);
    } finally {
      await late.context.close();
    }
  } finally {
    await first.context.close();
  }
  assertNoPageProblems();
});

/**
 * A viewer in Chromium that reads its video socket slowly (one message every `delayMs`, far
 * slower than the camera sends): WebSocketStream reads only when asked, so the socket's
 * buffers fill and the server sees a slow viewer, as over a slow link. (Chromium's network
 * emulation would not do: it holds the bytes in the browser, the server never sees them wait.)
 */
async function throttledViewer(path, delayMs) {
  const context = await browser.newContext();
  const page = await context.newPage();
  await page.goto(`${BASE}/api/health`);
  await page.evaluate(
    async ({ path, delayMs }) => {
      const slow = { frames: [], skipped: [], events: [], closed: null };
      window.slow = slow;
      const ws = new WebSocketStream(`ws://${location.host}${path}?vsn=1`);
      const { readable } = await ws.opened;
      const reader = readable.getReader();
      ws.closed.then(
        (c) => (slow.closed = `closed ${c.closeCode}`),
        (e) => (slow.closed = `failed ${e}`),
      );
      (async () => {
        for (;;) {
          const { value, done } = await reader.read();
          if (done) return;
          if (typeof value === "string") {
            const e = JSON.parse(value);
            slow.events.push(e.event);
            if (e.event === "skipped") slow.skipped.push({ frames: e.frames, at: slow.frames.length });
          } else {
            const v = value instanceof ArrayBuffer ? new DataView(value) : new DataView(value.buffer, value.byteOffset, value.byteLength);
            slow.frames.push({ seq: v.getUint32(8), key: (v.getUint8(2) & 1) === 1, gen: v.getUint32(4) });
          }
          await new Promise((r) => setTimeout(r, delayMs));
        }
      })();
    },
    { path, delayMs },
  );
  return { context, page };
}

test("a throttled viewer drops whole GOPs; another viewer stays live", { timeout: 120_000 }, async () => {
  assert.ok(BUSY_VEHICLE, "E2E_BUSY_VEHICLE names a vehicle with a heavy camera");
  const live = await videoPage({ name: "e2e-video-live", vehicle: BUSY_VEHICLE });
  let slow = null;
  try {
    await waitVideo(live.page, () => window.neptunusVideo?.displayed >= 10, null, "the live viewer's pictures");
    // a viewer reading 10 messages a second of a 30 fps camera
    slow = await throttledViewer(`/video/${encodeURIComponent(BUSY_VEHICLE)}/websocket`, 100);
    const liveAt = await counters(live.page);
    try {
      await slow.page.waitForFunction(() => window.slow.skipped.length >= 1 && window.slow.frames.length > window.slow.skipped[0].at, null, { timeout: 90_000, polling: 200 });
    } catch (err) {
      throw new Error(`the server never skipped frames for the throttled viewer: ${JSON.stringify(await slow.page.evaluate(() => ({ ...window.slow, frames: window.slow.frames.slice(-10) })))}`, { cause: err });
    }
    const seen = await slow.page.evaluate(() => window.slow);
    // after each skip: a keyframe, and a gap in the sequence numbers as long as the skip said
    // (the test server closes a socket a send waited 2 s for: a page this slow on a busy
    // machine may be closed after its skips — a viewer gone, the others unaffected)
    let checked = 0;
    for (const { frames, at } of seen.skipped) {
      const before = seen.frames[at - 1];
      const next = seen.frames[at];
      if (before === undefined || next === undefined || before.gen !== next.gen) continue;
      assert.equal(next.key, true, `the frame after a skip of ${frames} is a keyframe`);
      assert.equal(next.seq - before.seq - 1, frames, "the skip's count is the gap in the sequence");
      checked += 1;
    }
    assert.ok(checked >= 1, `a skip between frames of one stream: ${JSON.stringify(seen.skipped)}`);
    // meanwhile the live viewer went on: pictures, nothing skipped, its picture fresh
    await waitVideo(live.page, (k) => window.neptunusVideo.displayed >= k + 60, liveAt.displayed, "the live viewer's next 60 pictures");
    // (a page on a machine this busy may be skipped a little itself: that is its own slowness,
    // which bench/video_latency measures; here it must go on, at the live edge)
    const liveAfter = await counters(live.page);
    assert.ok(liveAfter.serverToDisplay < 1000, `the live viewer's picture is ${liveAfter.serverToDisplay} ms old`);
    console.log(
      `# throttled viewer: ${seen.frames.length} frames read, ${seen.skipped.length} skips (${seen.skipped.map((s) => s.frames).join(", ")} frames), socket ${seen.closed ?? "open"}; ` +
        `live viewer: ${liveAfter.displayed - liveAt.displayed} pictures, ${liveAfter.skipped - liveAt.skipped} frames skipped, server→display ${liveAfter.serverToDisplay?.toFixed(0)} ms`,
    );
  } finally {
    await slow?.context.close();
    await live.context.close();
  }
  assertNoPageProblems();
});

test("a camera restart is recovered without a reload", { timeout: 120_000 }, async () => {
  assert.ok(RESTART_VEHICLE, "E2E_RESTART_VEHICLE names a vehicle whose camera ends and is restarted");
  for (const path of ["webcodecs", "mse"]) {
    const { context, page } = await videoPage({ name: `e2e-video-restart-${path}`, vehicle: RESTART_VEHICLE, video: path });
    try {
      await page.evaluate(() => {
        window.__sameDocument = true;
      });
      await waitVideo(page, () => window.neptunusVideo?.displayed >= 5 && window.neptunusVideo.generation !== null, null, "pictures of the first generation");
      const g = (await counters(page)).generation;
      const width = await pictureWidth(page);
      await waitVideo(page, (gen) => window.neptunusVideo.generation !== gen, g, "a new generation (the camera restarted)", 60_000);
      const c = await counters(page);
      await waitVideo(page, (k) => window.neptunusVideo.displayed >= k + 5, c.displayed, "pictures of the new generation");
      assert.equal(await page.evaluate(() => window.__sameDocument), true, "the page was not reloaded");
      const after = await counters(page);
      assert.equal(after.path, path);
      // the fixture's camera alternates 640x360 and 320x240: the new decoder has the new size
      assert.notEqual(await pictureWidth(page), width, "the picture's size changed with the restart");
      assert.ok(after.configures > c.configures - 1 && after.configures >= 2, `a new decoder for the new stream (${after.configures} set up)`);
    } finally {
      await context.close();
    }
  }
  assertNoPageProblems();
});

test("Snapshots: the button and the gamepad's button save the picture on the server; the developer page lists them", { timeout: TEST_MS }, async () => {
  const { context, page } = await videoPage({ name: "e2e-video-snapshot", init: stubPad });
  /** The name in the next "Snapshot saved: NAME" message that is not `previous`'s. */
  const saved = async (what, previous = null) => {
    const text = await until(
      () => page.locator("#message").textContent(),
      (t) => /^Snapshot saved: /.test(t ?? "") && t !== `Snapshot saved: ${previous}`,
      30_000,
      `the snapshot saved (${what})`,
    );
    return text.replace(/^Snapshot saved: /, "").trim();
  };
  try {
    // a known start: this server's local user has the default mapping (snapshot on 17; the
    // page has it from the start, and the server has none to replace it with)
    await page.evaluate(() => fetch("/api/settings/gamepad.mapping", { method: "DELETE" }));
    await page.reload();
    await waitVideo(page, () => window.neptunusVideo?.displayed >= 5, null, "pictures");
    await page.locator('[data-testid="snapshot"]').click();
    const byButton = await saved("the Snapshot button");
    assert.ok(byButton.startsWith(`${VEHICLE}-`) && byButton.endsWith(".jpg"), `the snapshot's name: ${byButton}`);
    // the gamepad's snapshot button (17 by default; buttons act in every input mode)
    await pressButton(page, 17);
    const byPad = await saved("the gamepad's button", byButton);
    const dev = await context.newPage();
    await dev.goto(`${BASE}/dev.html?vehicle=${encodeURIComponent(VEHICLE)}`);
    await dev.locator("#snapshots summary").click();
    for (const name of [byButton, byPad]) {
      const item = dev.locator(`[data-testid="snapshot-list"] li[data-name="${name}"]`);
      await item.waitFor();
      const href = await item.locator("a").getAttribute("href");
      const res = await fetch(`${BASE}${href}`);
      assert.equal(res.status, 200);
      assert.equal(res.headers.get("content-type"), "image/jpeg");
      const bytes = new Uint8Array(await res.arrayBuffer());
      assert.deepEqual([...bytes.subarray(0, 2)], [0xff, 0xd8], "a JPEG");
    }
  } finally {
    await context.close();
  }
  assertNoPageProblems();
});
