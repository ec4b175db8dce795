// Soak benchmark client (bench/soak starts the server and this script): a pilot drives a vehicle
// (thrust at SOAK_THRUST_HZ, heartbeat every 100 ms) while SOAK_OBSERVERS observers watch it, for
// SOAK_MINUTES; every SOAK_INTERVAL_MINUTES it prints the server's RSS, process count, largest
// message queues, the control latency p99, the telemetry delivery p99 and the recordings' size,
// and where the server's memory is (see below). At the end: memory flat (RSS growth after
// SOAK_WARMUP_MINUTES < 5 %, and live data after a forced GC < 5 %) and latency flat.
// Prints figures, asserts nothing (exit 0 unless it cannot run).
//
// What it measures, exactly:
//   * control latency: pilot `thrust` sent -> its phx_reply received (the reply comes after the
//     helm has handed the command to the board link). Also: thrust sent -> the first telemetry
//     frame (on the pilot's socket) whose thrusters.port_us is the commanded pulse width. The
//     SITL board's line is inside the server, so go(...) bytes on the board are not timed here
//     (bench/control_latency times them on a real pty).
//   * telemetry delivery: observer receive time - payload.sent_at (ms since the epoch, one machine
//     clock), every telemetry frame of every observer; includes the observers' event-loop delay.
//   * server RSS (/proc/<pid>/status), process count, message queues, erlang:memory(total): the
//     BEAM itself, through a hidden Erlang node (erl -sname, SOAK_NODE / SOAK_COOKIE) running
//     bench/support/soak_probe.erl (compiled into SOAK_PROBE_EBIN, loaded into the server's node
//     at the first row). Indented under each row: erlang:memory() by type, the allocators'
//     carriers (held from the OS: what RSS follows) and blocks (in use), the processes' data (heap
//     words in use, not heap blocks), the 5 largest processes
//     (memory, heap, refc binaries referenced, queue), the recorder's and telemetry's state size.
//   * memory after a forced GC (`after GC` lines): every process garbage-collected, then the same
//     figures, at the first row after the warm-up and the last (SOAK_GC_EVERY_ROW=1: every row).
//     What a GC gives back was garbage; growth that survives it is live data (a leak), growth of
//     RSS/carriers alone is the allocators keeping memory after a load spike.
//
// Environment: SOAK_URL, SOAK_VEHICLE (rov), SOAK_MINUTES (60), SOAK_OBSERVERS (500),
// SOAK_INTERVAL_MINUTES (5), SOAK_WARMUP_MINUTES (10), SOAK_THRUST_HZ (10), SOAK_SERVER_PID,
// SOAK_NODE, SOAK_COOKIE, SOAK_PROBE_EBIN, SOAK_GC_EVERY_ROW (0), SOAK_RECORDINGS (directory),
// SOAK_WINDOW (100 connects in flight).

import { createRequire } from 'node:module';
import { Worker, isMainThread, parentPort, workerData } from 'node:worker_threads';
import { readFileSync, readdirSync, statSync } from 'node:fs';
import { execFile } from 'node:child_process';
import { fileURLToPath } from 'node:url';
import { performance } from 'node:perf_hooks';
import os from 'node:os';
import path from 'node:path';
import { channelsSocket } from './support/channels.mjs';
import { BINS, histPct, pct } from './support/stats.mjs';

const require = createRequire(new URL('../assets/package.json', import.meta.url));
const WebSocket = require('ws');
const nowMs = () => performance.timeOrigin + performance.now();
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const num = (v, d) => { const n = Number(v ?? ''); return Number.isFinite(n) && n > 0 ? n : d; };

const URL_BASE = process.env.SOAK_URL ?? 'ws://127.0.0.1:4212';
const VEHICLE = process.env.SOAK_VEHICLE ?? 'rov';
const TOPIC = `vehicle:${VEHICLE}`;
const wsUrl = (name) => `${URL_BASE}/socket/websocket?vsn=2.0.0&name=${name}`;


async function main() {
  const MINUTES = num(process.env.SOAK_MINUTES, 60);
  const N = Math.floor(num(process.env.SOAK_OBSERVERS, 500));
  const INTERVAL = num(process.env.SOAK_INTERVAL_MINUTES, 5) * 60_000;
  const WARMUP = num(process.env.SOAK_WARMUP_MINUTES, 10) * 60_000;
  const THRUST_HZ = num(process.env.SOAK_THRUST_HZ, 10);
  const SERVER_PID = Number(process.env.SOAK_SERVER_PID ?? 0);
  const RECORDINGS = process.env.SOAK_RECORDINGS;

  const rssKb = () => {
    try { return Number(/VmRSS:\s+(\d+)/.exec(readFileSync(`/proc/${SERVER_PID}/status`, 'utf8'))[1]); } catch { return NaN; }
  };
  const dirBytes = (dir) => {
    let total = 0, files = 0;
    const walk = (d) => {
      for (const e of readdirSync(d, { withFileTypes: true })) {
        const p = path.join(d, e.name);
        if (e.isDirectory()) walk(p); else { total += statSync(p).size; files++; }
      }
    };
    try { walk(dir); } catch { /* not created yet */ }
    return { total, files };
  };

  // The pilot.
  const pilot = await connect('soakpilot');
  const join = await pilot.push(TOPIC, 'phx_join', {});
  if (join.status !== 'ok') throw new Error(`pilot join: ${JSON.stringify(join.response)}`);
  const grant = await pilot.push(TOPIC, 'request_control', {});
  if (grant.status !== 'ok' || grant.response.status !== 'granted') throw new Error(`request_control: ${JSON.stringify(grant)}`);
  let epoch = grant.response.grant.epoch;
  let stops = 0, lastStop = '', cmdErrors = 0, lastError = '', timeouts = 0;
  let reply = [], toTelemetry = [];
  let pending = null; // {us, sent}: the newest command not yet seen in telemetry
  pilot.onEvent = (event, payload) => {
    // a grant, and a deadman stop (`helm` with a new epoch), give the stamp for the next thrust
    if ((event === 'control_granted' || event === 'helm') && payload.epoch != null) epoch = payload.epoch;
    else if (event === 'stopped') { stops++; lastStop = payload.reason; }
    else if (event === 'telemetry' && payload.thrusters) {
      if (pending && payload.thrusters.port_us === pending.us) { toTelemetry.push(performance.now() - pending.sent); pending = null; }
    }
  };
  const heartbeat = setInterval(() => { pilot.push(TOPIC, 'heartbeat', {}).catch(() => {}); }, 100);

  // Observers: worker threads.
  const WORKERS = Math.min(2, Math.max(1, N));
  const workers = [];
  for (let w = 0; w < WORKERS; w++) {
    const ids = []; for (let k = w; k < N; k += WORKERS) ids.push(k);
    const worker = new Worker(fileURLToPath(import.meta.url), {
      workerData: { ids, window: Math.max(1, Math.floor(num(process.env.SOAK_WINDOW, 100) / WORKERS)) },
    });
    worker.on('error', (e) => { console.error('observer worker crashed:', e); process.exit(2); });
    workers.push(worker);
  }
  let seq = 0;
  const ask = (worker, cmd) => new Promise((resolve) => {
    const id = ++seq;
    const on = (m) => { if (m.id === id) { worker.off('message', on); resolve(m); } };
    worker.on('message', on); worker.postMessage({ id, cmd });
  });
  const askAll = (cmd) => Promise.all(workers.map((w) => ask(w, cmd)));
  const opened = await askAll('open');
  const joined = opened.reduce((a, r) => a + r.joined, 0);

  console.log(`# soak: ${MINUTES} min, ${joined}/${N} observers joined, pilot thrust ${THRUST_HZ} Hz + heartbeat 10 Hz on ${TOPIC} (${URL_BASE})`);
  console.log(`# figures every ${INTERVAL / 60000} min; memory/latency flatness judged after ${WARMUP / 60000} min; ${os.cpus().length} cores; load average ${os.loadavg().map((x) => x.toFixed(2)).join(' ')}`);
  console.log('# control = thrust -> phx_reply; ->telem = thrust -> first telemetry frame showing its port_us; ' +
    'delivery = observer arrival - sent_at');

  // Thrust: a sweep of surge 0.02 .. 0.80 (consecutive commands always differ, so each one is
  // a new go() on the line).
  let i = 0;
  const usOf = new Map();
  const thrust = setInterval(() => {
    i++;
    const s = ((i % 40) + 1) / 50;
    const sent = performance.now();
    // the pulse width this surge gives, as the server's earlier replies said (wiring-independent)
    pending = usOf.has(s) ? { us: usOf.get(s), sent } : null;
    let done = false;
    const t = setTimeout(() => { if (!done) timeouts++; }, 5000);
    pilot.push(TOPIC, 'thrust', { mode: 'motion', surge: s, heave: 0, yaw: 0, epoch }).then((r) => {
      done = true; clearTimeout(t);
      if (r.status !== 'ok') { cmdErrors++; lastError = JSON.stringify(r.response); }
      else if (r.response?.thrusters?.port_us != null) usOf.set(s, r.response.thrusters.port_us);
      reply.push(performance.now() - sent);
    });
  }, 1000 / THRUST_HZ);

  // The server-side figures (bench/support/soak_probe.erl, compiled by bench/soak into
  // SOAK_PROBE_EBIN): `stats`, or `gc` (every process garbage-collected first).
  const probe = (mode = 'stats') => new Promise((resolve) => {
    if (!process.env.SOAK_NODE || !process.env.SOAK_PROBE_EBIN) return resolve(null);
    execFile('erl', ['-hidden', '-noshell', '-sname', `soakprobe${process.pid}`, '-setcookie', process.env.SOAK_COOKIE,
      '-pa', process.env.SOAK_PROBE_EBIN, '-eval', 'soak_probe:main()', '--', process.env.SOAK_NODE, mode],
    { timeout: 90_000 }, (err, stdout) => {
      if (err) return resolve({ error: String(err.message).split('\n')[0] });
      try { resolve(JSON.parse(stdout.trim().split('\n').pop())); } catch { resolve({ error: stdout.slice(0, 200) }); }
    });
  });
  const MiB = (b) => (Number.isFinite(b) ? (b / 1048576).toFixed(1) : 'n/a');
  const KiB = (b) => (Number.isFinite(b) ? (b / 1024).toFixed(1) : 'n/a');
  // Where the memory is, one indented line (after a forced GC: `gc`).
  const memLine = (srv, label) => {
    if (!srv || srv.error) return `  ${label}: n/a ${srv?.error ?? ''}`;
    const m = srv.memory;
    const st = Object.fromEntries((srv.states ?? []).map((x) => [x.name, x]));
    const part = (x) => (x?.found ? `state ${KiB(x.state)} KiB, process ${KiB(x.memory)} KiB, binaries ${KiB(x.binary)} KiB` : 'not found');
    return `  ${label}: total ${MiB(m.total)} = processes ${MiB(m.processes)} (data in them ${MiB(srv.processes_live)}) + system ${MiB(m.system)} ` +
      `(binary ${MiB(m.binary)}, ets ${MiB(m.ets)}, code ${MiB(m.code)}, atom ${MiB(m.atom)}) MiB; ` +
      `allocator carriers ${MiB(srv.carriers)} MiB, blocks in use ${MiB(srv.blocks)} MiB` +
      (srv.mode === 'gc' ? `; before the GC: total ${MiB(srv.gc_before_total)} MiB (GC took ${srv.gc_ms} ms)` : '') +
      `\n  ${label} largest: ${(srv.largest ?? []).map((p) => `${p.who} ${KiB(p.memory)} KiB (heap ${KiB(p.heap)}, binaries ${KiB(p.binary)}, queue ${p.queue})`).join('; ')}` +
      `\n  ${label} recorder: ${part(st.recorder)}; telemetry: ${part(st.telemetry)}`;
  };
  const GC_EVERY_ROW = process.env.SOAK_GC_EVERY_ROW === '1';

  const rows = [];
  let closed = 0;
  const header = ['min', 'RSS MiB', 'BEAM MiB', 'procs', 'max queue (whose)', 'control p50/p99', '->telem p99', 'delivery p50/p99', 'telem/s', 'recording MiB'];
  console.log(header.join(' | '));
  const t0 = performance.now();
  const f1 = (x) => (Number.isFinite(x) ? x.toFixed(1) : 'n/a');
  const take = async (label) => {
    const r = reply, tt = toTelemetry; reply = []; toTelemetry = [];
    const obs = await askAll('take');
    const hist = new Float64Array(BINS + 1);
    for (const o of obs) for (let b = 0; b <= BINS; b++) hist[b] += o.hist[b];
    const frames = obs.reduce((a, o) => a + o.frames, 0);
    closed = obs.reduce((a, o) => a + o.closedByServer, 0);
    const srv = await probe();
    const rec = RECORDINGS ? dirBytes(RECORDINGS) : { total: NaN, files: 0 };
    const row = {
      min: (performance.now() - t0) / 60000, rss: rssKb() / 1024,
      beam: srv?.memory?.total != null ? srv.memory.total / 1048576 : NaN, procs: srv?.procs ?? NaN,
      srv, gc: null,
      queue: srv?.queues ? srv.queues.map((q) => `${q.len} ${q.who}`).join(', ') : `n/a ${srv?.error ?? ''}`,
      c50: pct(r, 50), c99: pct(r, 99), t99: pct(tt, 99), d50: histPct(hist, 50), d99: histPct(hist, 99),
      rate: frames / ((label.secs) || 1), rec: rec.total / 1048576, files: rec.files,
    };
    rows.push(row);
    console.log([f1(row.min), f1(row.rss), f1(row.beam), row.procs, row.queue, `${f1(row.c50)}/${f1(row.c99)} ms`,
      `${f1(row.t99)} ms`, `${f1(row.d50)}/${f1(row.d99)} ms`, f1(row.rate), `${f1(row.rec)} (${row.files} files)`].join(' | '));
    console.log(memLine(srv, 'memory'));
    // after a forced GC: at the first row after the warm-up, the last row (label.last) and,
    // with SOAK_GC_EVERY_ROW=1, every row (the GC is the last thing a row does)
    if (GC_EVERY_ROW || label.last || (!gcBase && row.min >= WARMUP / 60000 - 0.01)) {
      row.gc = await probe('gc');
      if (!gcBase && row.min >= WARMUP / 60000 - 0.01 && row.gc && !row.gc.error) gcBase = row;
      console.log(memLine(row.gc, 'after GC'));
    }
  };
  let gcBase = null;

  const end = t0 + MINUTES * 60_000;
  let last = performance.now();
  while (performance.now() < end - 1000) {
    await sleep(Math.min(INTERVAL, end - performance.now()));
    const now = performance.now();
    await take({ secs: (now - last) / 1000, last: performance.now() >= end - 1000 });
    last = now;
  }
  clearInterval(thrust);

  // Verdicts.
  const after = rows.filter((r) => r.min >= WARMUP / 60000 - 0.01);
  const base = after[0], fin = rows[rows.length - 1];
  console.log(`# load average at the end: ${os.loadavg().map((x) => x.toFixed(2)).join(' ')}`);
  console.log(`# observer sockets closed by the server: ${closed} of ${joined}`);
  console.log(`# pilot: ${stops} stopped events (last: ${lastStop || '-'}), ${cmdErrors} command errors${cmdErrors ? ` (last ${lastError})` : ''}, ${timeouts} replies later than 5 s`);
  if (!base || base === fin) {
    console.log(`# memory flat: n/a (no sample after the ${WARMUP / 60000} min warm-up besides the last; run longer or lower SOAK_WARMUP_MINUTES)`);
  } else {
    const g = (fin.rss - base.rss) / base.rss * 100, gb = (fin.beam - base.beam) / base.beam * 100;
    console.log(`# memory flat: ${g < 5 ? 'yes' : 'NO'} — RSS ${f1(base.rss)} -> ${f1(fin.rss)} MiB (${g.toFixed(1)} %) from minute ${f1(base.min)} to ${f1(fin.min)}; ` +
      `erlang:memory(total) ${f1(base.beam)} -> ${f1(fin.beam)} MiB (${gb.toFixed(1)} %); processes ${base.procs} -> ${fin.procs}`);
    // live data after the GC: the processes' data (not their heap blocks, whose size after a
    // GC depends on their size before it) + everything else erlang:memory counts (system)
    const live = (r) => (r?.gc?.memory && r.gc.processes_live != null ? r.gc.memory.system + r.gc.processes_live : undefined);
    if (gcBase && gcBase !== fin && live(fin) != null) {
      const a = live(gcBase), b = live(fin), gg = (b - a) / a * 100;
      const tg = (fin.gc.memory.total - gcBase.gc.memory.total) / gcBase.gc.memory.total * 100;
      const parts = ['binary', 'ets', 'code', 'atom']
        .map((k) => `${k} ${MiB(gcBase.gc.memory[k])} -> ${MiB(fin.gc.memory[k])}`).join(', ');
      console.log(`# memory after a forced GC flat: ${gg < 5 ? 'yes' : 'NO'} — live data after garbage-collecting every process ` +
        `(erlang:memory(system) + the processes' data) ${MiB(a)} -> ${MiB(b)} MiB (${gg.toFixed(1)} %, flat: < 5 %) ` +
        `from minute ${f1(gcBase.min)} to ${f1(fin.min)}: processes' data ${MiB(gcBase.gc.processes_live)} -> ${MiB(fin.gc.processes_live)}, ` +
        `${parts} MiB; erlang:memory(total) after the GC ${MiB(gcBase.gc.memory.total)} -> ${MiB(fin.gc.memory.total)} MiB (${tg.toFixed(1)} %, ` +
        `processes' heap blocks ${MiB(gcBase.gc.memory.processes)} -> ${MiB(fin.gc.memory.processes)}); ` +
        `allocator carriers ${MiB(gcBase.gc.carriers)} -> ${MiB(fin.gc.carriers)} MiB, blocks in use ${MiB(gcBase.gc.blocks)} -> ${MiB(fin.gc.blocks)} MiB` +
        (g >= 5 && gg < 5 ? ' — RSS grew but live data did not: allocator retention, not a leak' : ''));
    } else {
      console.log('# memory after a forced GC flat: n/a (no forced GC after the warm-up besides the last row)');
    }
    const ok = (a, b) => b <= 1.5 * a + 2; // last interval's p99 within 1.5x + 2 ms of the first after warm-up
    console.log(`# latency flat: ${ok(base.c99, fin.c99) && ok(base.d99, fin.d99) ? 'yes' : 'NO'} — control p99 ${f1(base.c99)} -> ${f1(fin.c99)} ms, ` +
      `delivery p99 ${f1(base.d99)} -> ${f1(fin.d99)} ms (flat: last <= 1.5 x first after warm-up + 2 ms); ` +
      `worst interval: control ${f1(Math.max(...after.map((r) => r.c99)))} ms, delivery ${f1(Math.max(...after.map((r) => r.d99)))} ms`);
  }
  clearInterval(heartbeat);
  await askAll('close');
  pilot.close();
  await Promise.all(workers.map((w) => w.terminate()));
  process.exit(0);
}

// A raw Phoenix Channels v2 socket: push() resolves with the phx_reply payload.
function connect(name) {
  return channelsSocket(WebSocket, wsUrl(name), {
    onClosed: (code) => console.error(`pilot socket closed by the server (${code})`),
  });
}

// A worker thread of observers: opens its sockets, then collects telemetry delivery latencies
// until asked for them ('take'), heartbeating every 30 s as the pages do.
function observers({ ids, window }) {
  const sockets = [];
  let hist = new Uint32Array(BINS + 1), frames = 0, closedByServer = 0;
  const prefix = `[null,null,${JSON.stringify(TOPIC)},"telemetry",`;
  const openOne = (k) => new Promise((resolve) => {
    const ws = new WebSocket(wsUrl(`obs${k}`), { perMessageDeflate: false });
    let joined = false;
    ws.on('message', (data) => {
      const text = data.toString();
      if (text.startsWith(prefix)) {
        frames++;
        const m = /"sent_at":([0-9.e+]+)/.exec(text);
        if (m) hist[Math.min(BINS, Math.max(0, Math.floor((nowMs() - Number(m[1])) * 10)))]++;
      } else if (!joined && text.startsWith('["j","j"')) { joined = true; resolve(text.includes('"status":"ok"')); }
    });
    ws.once('open', () => ws.send(JSON.stringify(['j', 'j', TOPIC, 'phx_join', {}])));
    ws.once('error', () => resolve(false));
    ws.on('close', () => { if (!ws.closing) closedByServer++; });
    sockets.push(ws);
    setInterval(() => { if (ws.readyState === 1) ws.send(JSON.stringify([null, 'hb', 'phoenix', 'heartbeat', {}])); }, 30000).unref();
  });
  parentPort.on('message', async ({ id, cmd }) => {
    if (cmd === 'open') {
      let next = 0, joined = 0;
      await Promise.all(Array.from({ length: Math.min(window, ids.length) }, async () => {
        while (next < ids.length) { if (await openOne(ids[next++])) joined++; }
      }));
      parentPort.postMessage({ id, joined });
    } else if (cmd === 'take') {
      parentPort.postMessage({ id, hist, frames, closedByServer });
      hist = new Uint32Array(BINS + 1); frames = 0;
    } else if (cmd === 'close') {
      for (const ws of sockets) { ws.closing = true; ws.close(1000); }
      await sleep(500);
      parentPort.postMessage({ id });
    }
  });
}

if (isMainThread) await main(); else observers(workerData);
