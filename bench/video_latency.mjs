// Video latency with real Chromium pages as viewers: glass-to-glass (render→display, read by
// each page from the sim camera's corner stamp), frames delivered per viewer, the server's CPU,
// and what one throttled viewer does to the others. Prints figures, asserts nothing.
// Started by bench/video_latency, which starts the server; alone against a running server:
//
//   VLAT_URL=http://127.0.0.1:4000 VLAT_VEHICLE=neptunus-1 VLAT_SERVER_PID=<beam pid> \
//     node bench/video_latency.mjs [VIEWERS] [SECONDS]
//
// VIEWERS: comma-separated counts measured in turn (default "1,10,50"); SECONDS per count
// (default 20). The viewers are pages in one headless Chromium, each its own renderer
// process: camera pages (`/camera.html?vehicle=V&video=PATH`: the picture, its health line,
// the vehicle joined as any watcher does) by default, operator pages (`/?vehicle=V`: the HUD,
// telemetry at 20 Hz, the panels and the player — about a third of a core per page here
// before any video) with VLAT_PAGE=operator. Each page's player keeps every render→display
// sample (`window.neptunusVideo.samples`); the bench empties them after a warm-up and reads
// them at the end of the window.
//
// The throttled viewer (VLAT_THROTTLED_WITH, counts default "1,10": measured after each of these
// counts' window, with its pages still open — with 1, where this machine keeps up, and with 10): one more Chromium page that reads its video socket slowly —
// one message every VLAT_THROTTLE_READ_MS (default 200: 5 a second of a 30 fps camera)
// through WebSocketStream, which reads only when asked, so the socket's buffers fill and the
// server sees a slow viewer as over a slow link. (Chromium's network emulation would not
// do: it holds the bytes in the browser, the server never sees them wait.) Once the server
// has skipped frames for it (its buffers full: up to a minute at the sim camera's bitrate)
// the others are measured again over SECONDS; the figures compare each page's p99 without
// and with it.
//
// Environment: VLAT_URL (http://127.0.0.1:4000), VLAT_VEHICLE (neptunus-1), VLAT_PAGE (camera |
// operator), VLAT_SERVER_PID
// (the BEAM's OS pid: its CPU and its child processes' — the camera — are printed),
// VLAT_PATH (auto | webcodecs | mse), VLAT_WARMUP_FRAMES (60), VLAT_WARMUP_S (60), VLAT_THROTTLED_WITH (1,10; 0:
// none), VLAT_THROTTLE_READ_MS (200), CHROMIUM_PATH (/usr/bin/chromium).

import { createRequire } from 'node:module';
import { existsSync, readFileSync, readdirSync } from 'node:fs';
import os from 'node:os';
import { pct } from './support/stats.mjs';

const require = createRequire(new URL('../assets/package.json', import.meta.url));
const { chromium } = require('playwright-core');

const BASE = (process.env.VLAT_URL ?? 'http://127.0.0.1:4000').replace(/\/+$/, '');
const VEHICLE = process.env.VLAT_VEHICLE ?? 'neptunus-1';
const PATH = process.env.VLAT_PATH ?? 'auto';
const PAGE = process.env.VLAT_PAGE ?? 'camera';
if (PAGE !== 'camera' && PAGE !== 'operator') throw new Error(`VLAT_PAGE must be camera or operator, got ${PAGE}`);
const COUNTS = (process.argv[2] ?? process.env.VLAT_VIEWERS ?? '1,10,50').split(',').map(Number);
const SECONDS = Number(process.argv[3] ?? process.env.VLAT_SECONDS ?? 20);
const WARMUP_FRAMES = Number(process.env.VLAT_WARMUP_FRAMES ?? 60);
const WARMUP_S = Number(process.env.VLAT_WARMUP_S ?? 60);
const THROTTLED_WITH = new Set((process.env.VLAT_THROTTLED_WITH ?? '1,10').split(',').map(Number));
const THROTTLE_READ_MS = Number(process.env.VLAT_THROTTLE_READ_MS ?? 200);
const SERVER_PID = Number(process.env.VLAT_SERVER_PID ?? 0);
const CHROMIUM = process.env.CHROMIUM_PATH ?? '/usr/bin/chromium';
const CLK_TCK = Number(process.env.VLAT_CLK_TCK ?? 100);

const out = (label, value) => console.log(`${(label + ':').padEnd(50)} ${value}`);
const ms = (v) => (Number.isFinite(v) ? `${v.toFixed(0)} ms` : 'n/a');
const sleep = (t) => new Promise((r) => setTimeout(r, t));

// ---------------------------------------------------------------------------------------
// CPU of the server (the BEAM) and of its child processes (the camera: renderer, ffmpeg)

function ticksOf(pid) {
  try {
    const stat = readFileSync(`/proc/${pid}/stat`, 'utf8');
    const f = stat.slice(stat.lastIndexOf(')') + 2).split(' ');
    // utime, stime, cutime, cstime are fields 14..17 (f[11..14] after the name)
    return Number(f[11]) + Number(f[12]);
  } catch {
    return null;
  }
}

function childrenOf(pid) {
  const kids = [];
  for (const name of readdirSync('/proc')) {
    if (!/^\d+$/.test(name)) continue;
    try {
      const stat = readFileSync(`/proc/${name}/stat`, 'utf8');
      const f = stat.slice(stat.lastIndexOf(')') + 2).split(' ');
      if (Number(f[1]) === pid) kids.push({ pid: Number(name), comm: stat.slice(stat.indexOf('(') + 1, stat.lastIndexOf(')')) });
    } catch {
      // gone
    }
  }
  return kids;
}

/** CPU ticks of the server and of each of its children (by pid) now. */
function cpuNow() {
  if (!SERVER_PID) return null;
  const kids = childrenOf(SERVER_PID);
  // grandchildren too: the camera may be a shell running the renderer and ffmpeg
  for (const k of [...kids]) kids.push(...childrenOf(k.pid));
  return { at: performance.now(), server: ticksOf(SERVER_PID), kids: kids.map((k) => ({ ...k, ticks: ticksOf(k.pid) })) };
}

function cpuSince(a) {
  const b = cpuNow();
  if (a === null || b === null) return null;
  const seconds = (b.at - a.at) / 1000;
  const pctOf = (t0, t1) => (t0 === null || t1 === null ? NaN : ((t1 - t0) / CLK_TCK / seconds) * 100);
  const camera = b.kids.map((k) => {
    const before = a.kids.find((x) => x.pid === k.pid);
    return { comm: k.comm, pct: pctOf(before?.ticks ?? null, k.ticks) };
  });
  return { server: pctOf(a.server, b.server), camera };
}

function loadLine() {
  const [l1, l5] = os.loadavg();
  return `${l1.toFixed(2)} (1 min), ${l5.toFixed(2)} (5 min) on ${os.cpus().length} cores`;
}

// ---------------------------------------------------------------------------------------
// Pages

const ARGS = [
  '--no-sandbox',
  '--disable-gpu',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-background-timer-throttling',
  '--disable-renderer-backgrounding',
  '--disable-backgrounding-occluded-windows',
  '--autoplay-policy=no-user-gesture-required',
];

async function openViewer(browser, name) {
  const context = await browser.newContext({ viewport: { width: 1024, height: 768 } });
  const page = await context.newPage();
  page.on('pageerror', (err) => console.error(`[${name}] uncaught: ${err.message}`));
  const where = PAGE === 'camera' ? '/camera.html' : '/';
  await page.goto(`${BASE}${where}?vehicle=${encodeURIComponent(VEHICLE)}&name=${encodeURIComponent(name)}&video=${PATH}`, { waitUntil: 'load', timeout: 60_000 });
  return { name, context, page };
}

/** The slow reader (see the top): a page of this origin reading its socket at `readMs` per message. */
async function openThrottled(browser, readMs) {
  const context = await browser.newContext();
  const page = await context.newPage();
  page.on('pageerror', (err) => console.error(`[throttled] uncaught: ${err.message}`));
  await page.goto(`${BASE}/api/health`, { timeout: 60_000 });
  await page.evaluate(
    async ({ path, readMs }) => {
      const slow = { frames: 0, skips: 0, skipped: 0, closed: null };
      window.slow = slow;
      // a machine this busy may fail a handshake: three tries
      let ws;
      let readable;
      for (let attempt = 1; ; attempt++) {
        try {
          ws = new WebSocketStream(`ws://${location.host}${path}?vsn=1`);
          ({ readable } = await ws.opened);
          break;
        } catch (err) {
          if (attempt === 3) throw err;
          await new Promise((r) => setTimeout(r, 1000));
        }
      }
      ws.closed.then((c) => (slow.closed = `closed ${c.closeCode}`), (e) => (slow.closed = `failed ${e}`));
      const reader = readable.getReader();
      (async () => {
        for (;;) {
          const { value, done } = await reader.read();
          if (done) return;
          if (typeof value === 'string') {
            const e = JSON.parse(value);
            if (e.event === 'skipped') {
              slow.skips += 1;
              slow.skipped += e.frames;
            }
          } else {
            slow.frames += 1;
          }
          await new Promise((r) => setTimeout(r, readMs));
        }
      })();
    },
    { path: `/video/${encodeURIComponent(VEHICLE)}/websocket`, readMs },
  );
  return { context, page, state: () => page.evaluate(() => ({ ...window.slow })) };
}

async function counters(v) {
  return v.page.evaluate(() => {
    const c = window.neptunusVideo;
    if (!c) return null;
    const dropped = Object.values(c.dropped).reduce((a, b) => a + b, 0);
    return { path: c.path, received: c.received, displayed: c.displayed, dropped, skipped: c.skipped, superseded: c.superseded, errors: c.errors, stamps: c.stamps, misses: c.stampMisses, offsetKnown: c.serverToDisplay !== null };
  });
}

/**
 * Waits until every page has shown VLAT_WARMUP_FRAMES stamped pictures, at most
 * VLAT_WARMUP_S seconds (a machine too busy for that is measured as it is: the figures say so).
 */
async function waitWarm(viewers) {
  const deadline = Date.now() + WARMUP_S * 1000;
  for (;;) {
    const cs = await Promise.all(viewers.map(counters));
    const warm = cs.filter((c) => c !== null && c.stamps >= WARMUP_FRAMES).length;
    if (warm === viewers.length || Date.now() > deadline) {
      if (warm < viewers.length) out('warm-up', `${warm} of ${viewers.length} pages showed ${WARMUP_FRAMES} pictures within ${WARMUP_S} s; measuring as it is`);
      return;
    }
    await sleep(500);
  }
}

/** Empties every page's samples, waits SECONDS, returns each page's samples and counter deltas. */
async function measure(viewers) {
  const before = await Promise.all(viewers.map(counters));
  // a page whose script never loaded (a starved browser, the server closing its slow request) has no player
  const take = (v) => v.page.evaluate(() => window.neptunusVideo?.samples.splice(0) ?? []);
  await Promise.all(viewers.map(take));
  const cpu0 = cpuNow();
  const t0 = performance.now();
  await sleep(SECONDS * 1000);
  const samples = await Promise.all(viewers.map(take));
  const seconds = (performance.now() - t0) / 1000;
  const cpu = cpuSince(cpu0);
  const after = await Promise.all(viewers.map(counters));
  const none = { path: 'none', received: 0, displayed: 0, dropped: 0, skipped: 0, errors: 0 };
  const per = viewers.map((v, i) => {
    const a = after[i] ?? none;
    const b = before[i] ?? none;
    return {
      name: v.name,
      path: a.path,
      samples: samples[i],
      received: (a.received - b.received) / seconds,
      displayed: (a.displayed - b.displayed) / seconds,
      dropped: a.dropped - b.dropped,
      skipped: a.skipped - b.skipped,
      errors: a.errors - b.errors,
      p50: pct(samples[i], 50),
      p99: pct(samples[i], 99),
    };
  });
  return { per, cpu, seconds, playerless: after.filter((c) => c === null).length };
}

function report(label, m) {
  const all = m.per.flatMap((p) => p.samples);
  const mean = (xs) => xs.reduce((a, b) => a + b, 0) / Math.max(1, xs.length);
  out(`${label}: glass-to-glass p50 / p99 (all pages)`, `${ms(pct(all, 50))} / ${ms(pct(all, 99))}  (${all.length} pictures, render→display from the corner stamp)`);
  const worst = (xs) => Math.max(...xs.filter(Number.isFinite));
  out(`${label}: worst page's p50 / p99`, `${ms(worst(m.per.map((p) => p.p50)))} / ${ms(worst(m.per.map((p) => p.p99)))}`);
  if (m.playerless > 0) out(`${label}: pages without a player`, `${m.playerless} (their script never ran: counted as showing nothing)`);
  out(`${label}: frames received per viewer per s`, `mean ${mean(m.per.map((p) => p.received)).toFixed(1)}, min ${Math.min(...m.per.map((p) => p.received)).toFixed(1)}`);
  out(`${label}: pictures shown per viewer per s`, `mean ${mean(m.per.map((p) => p.displayed)).toFixed(1)}, min ${Math.min(...m.per.map((p) => p.displayed)).toFixed(1)}`);
  out(`${label}: frames dropped (all pages) / server-skipped`, `${m.per.reduce((n, p) => n + p.dropped, 0)} / ${m.per.reduce((n, p) => n + p.skipped, 0)}; decoder errors ${m.per.reduce((n, p) => n + p.errors, 0)}`);
  out(`${label}: decode path`, [...new Set(m.per.map((p) => p.path))].join(', '));
  if (m.cpu !== null) {
    const cam = m.cpu.camera.filter((c) => Number.isFinite(c.pct)).map((c) => `${c.comm} ${c.pct.toFixed(1)} %`).join(', ');
    out(`${label}: server CPU (BEAM) / camera processes`, `${m.cpu.server.toFixed(1)} % of one core / ${cam || 'none seen'}`);
  }
  out(`${label}: machine load`, loadLine());
}

/** The worst change of a page's p99 from window `a` to window `b`, and each page's. */
function changes(a, b) {
  const deltas = a.per.map((p, i) => b.per[i].p99 - p.p99);
  const worst = deltas.reduce((x, y) => (Math.abs(y) > Math.abs(x) ? y : x), 0);
  return `worst ${worst >= 0 ? '+' : ''}${worst.toFixed(0)} ms (per page: ${deltas.map((d) => d.toFixed(0)).join(' ')})`;
}

async function main() {
  if (!existsSync(CHROMIUM)) throw new Error(`no Chromium at ${CHROMIUM}`);
  console.log(`# video_latency: ${BASE}, vehicle ${VEHICLE}, ${PAGE} pages, path ${PATH}, ${SECONDS} s per measurement, viewers ${COUNTS.join(', ')}`);
  console.log(`# machine: ${os.cpus().length} × ${os.cpus()[0]?.model ?? '?'}, load ${loadLine()}`);
  const browser = await chromium.launch({ executablePath: CHROMIUM, args: ARGS, timeout: 60_000 });
  try {
    for (const n of COUNTS) {
      const viewers = [];
      let failed = 0;
      for (let i = 0; i < n; i++) {
        // a page the machine cannot open now (a busy server or browser) is tried twice more
        for (let attempt = 1; ; attempt++) {
          try {
            viewers.push(await openViewer(browser, `viewer-${n}-${i}`));
            break;
          } catch (err) {
            if (attempt === 3) {
              failed += 1;
              console.error(`viewer-${n}-${i} not opened: ${err.message.split('\n')[0]}`);
              break;
            }
            await sleep(2000);
          }
        }
      }
      if (failed > 0) out('pages not opened', `${failed} of ${n}`);
      await waitWarm(viewers);
      const label = `${n} viewer${n === 1 ? '' : 's'}`;
      const m = await measure(viewers);
      report(label, m);
      if (THROTTLED_WITH.has(n)) {
        // the same pages measured again without it: how much p99 moves between two windows anyway
        const again = await measure(viewers);
        out(`${label}, again: glass-to-glass p50 / p99`, `${ms(pct(again.per.flatMap((p) => p.samples), 50))} / ${ms(pct(again.per.flatMap((p) => p.samples), 99))}`);
        out(`${label}, again: change of each page's p99 (noise)`, changes(m, again));
        const t = await openThrottled(browser, THROTTLE_READ_MS);
        const t0 = Date.now();
        // its buffers fill first: measure once the server skips frames for it
        let first = 'none within 180 s';
        for (;;) {
          const st = await t.state();
          if (st.skips > 0) {
            first = `${((Date.now() - t0) / 1000).toFixed(0)} s (its buffers filling)`;
            break;
          }
          if (st.closed !== null) {
            first = `none: its socket ${st.closed}`;
            break;
          }
          if (Date.now() - t0 > 180_000) break;
          await sleep(500);
        }
        out('throttled viewer: first skip after', first);
        const tBefore = await t.state();
        const withT = await measure(viewers);
        const tAfter = await t.state();
        report(`${label} + 1 throttled`, withT);
        out('throttled viewer: change of the others\' p99', `${changes(again, withT)} (against the window just before it)`);
        out(`throttled viewer (reads 1 message / ${THROTTLE_READ_MS} ms)`, `${tAfter.frames - tBefore.frames} frames read, ${tAfter.skips - tBefore.skips} skips by the server (${tAfter.skipped - tBefore.skipped} frames), socket ${tAfter.closed ?? 'open'}`);
        await t.context.close();
      }
      await Promise.all(viewers.map((v) => v.context.close()));
    }
  } finally {
    await browser.close();
  }
}

main().catch((err) => {
  console.error(`video_latency: ${err.stack ?? err.message}`);
  process.exit(1);
});
