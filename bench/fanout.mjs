// Telemetry fan-out benchmark client: N observers on "vehicle:<id>" over raw
// Phoenix Channels v2 WebSockets (the `ws` package), spread over worker threads.
// Prints figures, asserts nothing. Started by bench/fanout (which starts the server);
// can also run against a server you started yourself:
//
//   FANOUT_SERVER_PID=<beam os pid> node bench/fanout.mjs [N] [SECONDS]
//
// Environment: FANOUT_N, FANOUT_SECONDS, FANOUT_URL (default ws://127.0.0.1:4210),
// FANOUT_VEHICLE (neptunus-1), FANOUT_WORKERS (2), FANOUT_WINDOW (100 connections or
// joins in flight at once), FANOUT_HZ (20, the expected telemetry rate),
// FANOUT_SERVER_PID (for RSS/CPU figures), FANOUT_CLK_TCK (100), FANOUT_PILOT (1: one more
// connection, in this thread, takes control of the vehicle before the measurement, so the
// telemetry is paced to the observers as during a dive; its own frames are not counted).

import { createRequire } from 'node:module';
import { Worker, isMainThread, parentPort, workerData } from 'node:worker_threads';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { monitorEventLoopDelay, performance } from 'node:perf_hooks';

const require = createRequire(new URL('../assets/package.json', import.meta.url));
const WebSocket = require('ws');

const nowMs = () => performance.timeOrigin + performance.now(); // epoch ms, sub-ms resolution

if (isMainThread) {
  await main();
} else {
  runWorker(workerData);
}

// ---------------------------------------------------------------------------
// Main thread: coordination, /proc sampling, figures.

async function main() {
  const int = (v, d) => {
    const n = Number.parseInt(v ?? '', 10);
    return Number.isFinite(n) && n > 0 ? n : d;
  };
  const N = int(process.argv[2] ?? process.env.FANOUT_N, 1000);
  const SECONDS = int(process.argv[3] ?? process.env.FANOUT_SECONDS, 10);
  const URL_BASE = process.env.FANOUT_URL ?? 'ws://127.0.0.1:4210';
  const VEHICLE = process.env.FANOUT_VEHICLE ?? 'neptunus-1';
  const WORKERS = Math.min(int(process.env.FANOUT_WORKERS, 2), N);
  const WINDOW = int(process.env.FANOUT_WINDOW, 100);
  const HZ = int(process.env.FANOUT_HZ, 20);
  const SERVER_PID = int(process.env.FANOUT_SERVER_PID, 0);
  const CLK_TCK = int(process.env.FANOUT_CLK_TCK, 100);

  const out = (label, value) => console.log(`${(label + ':').padEnd(44)} ${value}`);
  const f1 = (x) => (Number.isFinite(x) ? x.toFixed(1) : 'n/a');
  const f2 = (x) => (Number.isFinite(x) ? x.toFixed(2) : 'n/a');
  const mib = (kb) => (kb == null ? 'n/a' : `${(kb / 1024).toFixed(1)} MiB (${kb} kB)`);

  // /proc readers -----------------------------------------------------------
  const rssKb = (pid) => {
    if (!pid) return null;
    try {
      const m = /VmRSS:\s+(\d+)\s+kB/.exec(readFileSync(`/proc/${pid}/status`, 'utf8'));
      return m ? Number(m[1]) : null;
    } catch { return null; }
  };
  const cpuTicks = (pid) => { // utime + stime, clock ticks
    if (!pid) return null;
    try {
      const s = readFileSync(`/proc/${pid}/stat`, 'utf8');
      const f = s.slice(s.lastIndexOf(')') + 2).split(' '); // f[0] is field 3 (state)
      return Number(f[11]) + Number(f[12]); // fields 14 and 15
    } catch { return null; }
  };
  const machine = () => { // whole-machine busy/total jiffies (all processes, all cores)
    const f = readFileSync('/proc/stat', 'utf8').split('\n')[0].trim().split(/\s+/).slice(1).map(Number);
    const idle = f[3] + (f[4] || 0);
    const total = f.slice(0, 8).reduce((a, b) => a + b, 0);
    return { idle, total };
  };
  const cpuPressure = () => { // µs during which some runnable task waited for a CPU
    try { return Number(/some .*total=(\d+)/.exec(readFileSync('/proc/pressure/cpu', 'utf8'))[1]); } catch { return NaN; }
  };
  const sample = () => ({
    t: performance.now(),
    server: cpuTicks(SERVER_PID),
    client: process.cpuUsage(), // whole process: main thread + worker threads
    machine: machine(),
    psi: cpuPressure(),
  });
  const usage = (a, b) => {
    const wallS = (b.t - a.t) / 1000;
    const server = a.server != null && b.server != null ? ((b.server - a.server) / CLK_TCK / wallS) * 100 : NaN;
    const client = ((b.client.user + b.client.system - a.client.user - a.client.system) / 1e6 / wallS) * 100;
    const dt = b.machine.total - a.machine.total;
    const busy = dt > 0 ? (1 - (b.machine.idle - a.machine.idle) / dt) * 100 : NaN;
    const waiting = ((b.psi - a.psi) / 1e6 / wallS) * 100;
    return { server, client, busy, waiting, wallS };
  };

  // Workers ------------------------------------------------------------------
  const url = (k) => `${URL_BASE}/socket/websocket?vsn=2.0.0&name=obs${k}`;
  const workers = [];
  for (let w = 0; w < WORKERS; w++) {
    const ids = [];
    for (let k = w; k < N; k += WORKERS) ids.push(k);
    const worker = new Worker(fileURLToPath(import.meta.url), {
      workerData: { ids, urls: ids.map(url), topic: `vehicle:${VEHICLE}`, window: Math.max(1, Math.floor(WINDOW / WORKERS)) },
    });
    worker.unref();
    worker.on('error', (e) => { console.error(`worker ${w} crashed:`, e); process.exit(2); });
    workers.push(worker);
  }
  let seq = 0;
  const ask = (worker, cmd, extra = {}) => new Promise((resolve) => {
    const id = ++seq;
    const on = (msg) => { if (msg.id === id) { worker.off('message', on); resolve(msg); } };
    worker.on('message', on);
    worker.postMessage({ id, cmd, ...extra });
  });
  const askAll = (cmd, extra) => Promise.all(workers.map((w) => ask(w, cmd, extra)));
  const sum = (rs, k) => rs.reduce((a, r) => a + r[k], 0);
  await askAll('ping');

  console.log(`# fanout: ${N} observers of vehicle:${VEHICLE} on ${URL_BASE}, ${SECONDS} s measurement`);
  console.log(`# client: Node ${process.version}, ws ${require('ws/package.json').version}, ${WORKERS} worker threads, ` +
    `at most ${WINDOW} connects/joins in flight; server and client share this machine's ` +
    `${(await import('node:os')).availableParallelism()} cores`);
  console.log(`# load average before start: ${readFileSync('/proc/loadavg', 'utf8').split(' ').slice(0, 3).join(' ')}`);

  const rssBefore = rssKb(SERVER_PID);
  out('server pid', SERVER_PID || 'n/a (FANOUT_SERVER_PID not set)');
  out('server RSS before connecting', mib(rssBefore));

  // Connect ------------------------------------------------------------------
  const s0 = sample();
  let t = performance.now();
  const conn = await askAll('connect');
  const connectMs = performance.now() - t;
  const connected = sum(conn, 'ok');
  out('connected', `${connected} / ${N}`);
  if (connected < N) out('connect failures', conn.flatMap((r) => r.errors).slice(0, 5).join(' | ') + ` (${N - connected} in all)`);
  out('connect time (all sockets open)', `${connectMs.toFixed(0)} ms`);
  const rssOpen = rssKb(SERVER_PID);
  const sOpen = sample();
  const handshakes = Float64Array.from(conn.flatMap((r) => r.handshakes)).sort();
  out('  handshake p50 / p99 / max', `${f1(pct(handshakes, 50))} / ${f1(pct(handshakes, 99))} / ${f1(handshakes[handshakes.length - 1])} ms`);

  out('server RSS after opening (before joins)', mib(rssOpen));
  out('server bytes per open socket (not joined)', rssBefore != null && rssOpen != null
    ? `${Math.round(((rssOpen - rssBefore) * 1024) / N)} B` : 'n/a');
  const connectUse = usage(s0, sOpen);
  out('server / client CPU while connecting', `${f1(connectUse.server)} / ${f1(connectUse.client)} % of one core`);

  // Join ---------------------------------------------------------------------
  t = performance.now();
  const join = await askAll('join');
  const joinMs = performance.now() - t;
  const joined = sum(join, 'ok');
  out('joined', `${joined} / ${connected}`);
  if (joined < connected) out('join failures', join.flatMap((r) => r.errors).slice(0, 5).join(' | ') + ` (${connected - joined} in all)`);
  out('join time (all phx_reply ok)', `${joinMs.toFixed(0)} ms`);
  const joinLat = Float64Array.from(join.flatMap((r) => r.latencies)).sort();
  out('  join reply p50 / p99 / max', `${f1(pct(joinLat, 50))} / ${f1(pct(joinLat, 99))} / ${f1(joinLat[joinLat.length - 1])} ms`);

  // The pilot (FANOUT_PILOT=1): with someone in control, observers get telemetry in slices.
  let pilot = null;
  if (process.env.FANOUT_PILOT === '1') {
    pilot = await takeControl(`${URL_BASE}/socket/websocket?vsn=2.0.0&name=pilot`, `vehicle:${VEHICLE}`);
    out('pilot', 'in control (telemetry to observers is paced)');
  }

  // Settle: presence_diff storm of the joins (each join is broadcast to everyone joined
  // before) must drain before we measure; wait until no presence frame for 1 s (max 60 s).
  t = performance.now();
  for (;;) {
    await sleep(250);
    const polls = await askAll('poll');
    const last = Math.max(...polls.map((p) => p.lastPresenceAt));
    const now = nowMs();
    if ((now - last > 1000 && performance.now() - t > 1000) || performance.now() - t > 60_000) break;
  }
  const settleMs = performance.now() - t;
  const s1 = sample();
  const rssAfter = rssKb(SERVER_PID);
  const setupUse = usage(sOpen, s1);
  const pre = await askAll('poll');
  out('settle time (until presence_diff stopped)', `${settleMs.toFixed(0)} ms`);
  out('presence_diff frames received while joining', `${sum(pre, 'presenceDiffs')} (${f1(sum(pre, 'presenceBytes') / 1048576)} MiB incl. presence_state)`);
  out('server / client CPU while joining+settling', `${f1(setupUse.server)} / ${f1(setupUse.client)} % of one core over ${f1(setupUse.wallS)} s`);
  out('server RSS after connecting (joined, settled)', mib(rssAfter));
  out('server bytes per socket (RSS delta / N)', rssBefore != null && rssAfter != null && joined
    ? `${Math.round(((rssAfter - rssBefore) * 1024) / N)} B` : 'n/a');

  // Measure ------------------------------------------------------------------
  const start = nowMs();
  const end = start + SECONDS * 1000;
  await askAll('measure', { start, end });
  const m0 = sample();
  await sleep(SECONDS * 1000);
  const m1 = sample();
  await sleep(50); // let frames timestamped before `end` be handled
  const res = await askAll('stop');
  const rssEnd = rssKb(SERVER_PID);
  const use = usage(m0, m1);

  const received = sum(res, 'telemetry');
  const lat = new Float64Array(received);
  { let o = 0; for (const r of res) { lat.set(new Float64Array(r.latencies), o); o += r.latencies.byteLength / 8; } }
  lat.sort();
  const perSocket = res.flatMap((r) => r.perSocket).sort((a, b) => a - b);
  const expected = joined * HZ;

  out('messages received (telemetry)', received);
  out('messages/s, total', f1(received / SECONDS));
  out('messages/s, per socket', `${f2(received / SECONDS / Math.max(joined, 1))} (expected ${HZ})`);
  out('expected messages/s (joined × Hz)', `${expected} (received ${f1((received / SECONDS / Math.max(expected, 1)) * 100)} %)`);
  out('per-socket telemetry count min / p50 / max', `${perSocket[0] ?? 'n/a'} / ${perSocket[perSocket.length >> 1] ?? 'n/a'} / ${perSocket[perSocket.length - 1] ?? 'n/a'} (sockets with none: ${perSocket.filter((c) => c === 0).length})`);
  {
    // Broadcasts the server made in the window, from one socket's sent_at values per worker.
    const ts = [...new Set(res.flatMap((r) => r.ticks))].sort((a, b) => a - b);
    const gaps = Float64Array.from(ts.slice(1).map((x, i) => x - ts[i])).sort();
    out('server broadcasts seen (distinct sent_at)', `${ts.length} = ${f1(ts.length / SECONDS)} Hz (configured ${HZ} Hz)`);
    out('  interval between broadcasts p50/p99/max', `${f1(pct(gaps, 50))} / ${f1(pct(gaps, 99))} / ${f1(gaps[gaps.length - 1])} ms (nominal ${f1(1000 / HZ)})`);
  }
  out('delivery latency p50', `${f2(pct(lat, 50))} ms`);
  out('delivery latency p90', `${f2(pct(lat, 90))} ms`);
  out('delivery latency p99', `${f2(pct(lat, 99))} ms`);
  out('delivery latency max', `${f2(lat[lat.length - 1])} ms`);
  console.log('  (latency = client receive time - payload.sent_at, same machine clock; it includes the');
  console.log('   client\'s own event-loop delay, and server and client compete for the same cores)');
  const eld = res.map((r) => r.loopDelay);
  out('client event-loop delay p50 / p99 / max', `${f1(Math.max(...eld.map((e) => e.p50)))} / ${f1(Math.max(...eld.map((e) => e.p99)))} / ${f1(Math.max(...eld.map((e) => e.max)))} ms (worst worker)`);
  out('other frames during measurement', `presence_diff ${sum(res, 'presenceDiffs')}, heartbeat replies ${sum(res, 'heartbeatReplies')}, other ${sum(res, 'other')}`);
  out('sockets closed by server during measurement', `${sum(res, 'closedDuring')}${res.flatMap((r) => r.closeCodes).length ? ' codes ' + JSON.stringify(tally(res.flatMap((r) => r.closeCodes))) : ''}`);
  out('socket errors', `${sum(res, 'errorCount')}${res.flatMap((r) => r.errorSamples).length ? ' e.g. ' + res.flatMap((r) => r.errorSamples)[0] : ''}`);
  out('server CPU during measurement', `${f1(use.server)} % of one core`);
  out('client CPU during measurement', `${f1(use.client)} % of one core (${WORKERS} worker threads + main)`);
  out('machine CPU busy during measurement', `${f1(use.busy)} % of all cores (every process, incl. others on the machine)`);
  out('CPU pressure during measurement', `${f1(use.waiting)} % of the time some task waited for a core (/proc/pressure/cpu)`);
  out('server RSS after measurement', mib(rssEnd));

  // Close --------------------------------------------------------------------
  t = performance.now();
  const closed = await askAll('close');
  const closeMs = performance.now() - t;
  out('close: sockets closed', `${closed.reduce((a, r) => a + r.codes.length, 0)} in ${closeMs.toFixed(0)} ms`);
  out('close: codes seen by the client', JSON.stringify(tally(closed.flatMap((r) => r.codes))) +
    ' (1000 = server echoed the close frame; 1006 = TCP closed without a close frame)');
  out('close: clean (1000 echoed) / forced after 20 s', `${sum(closed, 'clean')} / ${sum(closed, 'forced')}`);
  await Promise.all(workers.map((w) => w.terminate()));
  // the pilot's open socket would keep this process (and so the run) alive
  if (pilot) await new Promise((resolve) => { pilot.once('close', resolve); pilot.close(1000); setTimeout(resolve, 2_000); });
}

function pct(sorted, p) {
  if (!sorted.length) return NaN;
  return sorted[Math.min(sorted.length - 1, Math.max(0, Math.ceil((p / 100) * sorted.length) - 1))];
}
function tally(xs) { const o = {}; for (const x of xs) o[x] = (o[x] || 0) + 1; return o; }
function sleep(ms) { return new Promise((r) => setTimeout(r, ms)); }

// A socket that joins `topic` and requests control; resolves once granted. It heartbeats every
// 20 s so the server keeps it; its telemetry is ignored.
function takeControl(url, topic) {
  return new Promise((resolve, reject) => {
    const ws = new WebSocket(url, { perMessageDeflate: false });
    ws.on('error', reject);
    ws.on('open', () => ws.send(JSON.stringify(['p', 'p1', topic, 'phx_join', {}])));
    ws.on('message', (data) => {
      const [, ref, , event, payload] = JSON.parse(data.toString());
      if (event !== 'phx_reply') return;
      if (ref === 'p1') ws.send(JSON.stringify(['p', 'p2', topic, 'request_control', {}]));
      if (ref === 'p2') {
        if (payload.status !== 'ok' || payload.response.status !== 'granted') {
          reject(new Error(`request_control: ${JSON.stringify(payload)}`));
          return;
        }
        setInterval(() => ws.send(JSON.stringify([null, 'hb', 'phoenix', 'heartbeat', {}])), 20_000).unref();
        resolve(ws);
      }
    });
  });
}

// ---------------------------------------------------------------------------
// Worker thread: owns a share of the sockets.

function runWorker({ ids, urls, topic, window }) {
  const enc = (s) => Buffer.from(s, 'latin1');
  const TELEMETRY = enc(`[null,null,${JSON.stringify(topic)},"telemetry",`);
  const PRESENCE_DIFF = enc(`[null,null,${JSON.stringify(topic)},"presence_diff",`);
  const SENT_AT = enc('"sent_at":');
  const JOIN = JSON.stringify(['1', '1', topic, 'phx_join', {}]);
  const HEARTBEAT_PERIOD = 30_000;

  const LOOP_RES_MS = 10;
  const loop = monitorEventLoopDelay({ resolution: LOOP_RES_MS }); // samples include the period itself
  const socks = ids.map((k, i) => ({
    k, url: urls[i], ws: null, open: false, joined: false, telemetry: 0, hbRef: 0, hbTimer: null,
    onJoin: null,
  }));

  // Measurement state
  let probe = null; // one joined socket whose sent_at values reveal the server's tick rate
  let ticks = [];
  let measuring = false;
  let mStart = 0;
  let mEnd = Infinity;
  let lat = new Float64Array(Math.max(1024, ids.length * 20 * 12));
  let nLat = 0;
  const st = {
    presenceDiffs: 0, presenceBytes: 0, heartbeatReplies: 0, other: 0,
    closedDuring: 0, closeCodes: [], errorCount: 0, errorSamples: [], lastPresenceAt: 0,
  };

  const startsWith = (buf, prefix) =>
    buf.length >= prefix.length && buf.compare(prefix, 0, prefix.length, 0, prefix.length) === 0;

  function sentAt(buf) { // parse the number after "sent_at": without JSON.parse
    const i = buf.indexOf(SENT_AT);
    if (i < 0) return NaN;
    let j = i + SENT_AT.length;
    let e = j;
    while (e < buf.length && ((buf[e] >= 48 && buf[e] <= 57) || buf[e] === 46 || buf[e] === 45 || buf[e] === 101 || buf[e] === 69 || buf[e] === 43)) e++;
    return Number(buf.latin1Slice(j, e));
  }

  function onMessage(s, data, isBinary) {
    const now = nowMs();
    if (isBinary) { st.other++; return; }
    if (startsWith(data, TELEMETRY)) {
      if (measuring && now >= mStart && now < mEnd) {
        const v = now - sentAt(data);
        if (nLat === lat.length) { const g = new Float64Array(lat.length * 2); g.set(lat); lat = g; }
        lat[nLat++] = v;
        s.telemetry++;
        if (s === probe) ticks.push(now - v);
      }
      return;
    }
    if (startsWith(data, PRESENCE_DIFF)) {
      st.presenceDiffs++; st.presenceBytes += data.length; st.lastPresenceAt = now;
      return;
    }
    const text = data.toString('utf8');
    if (text.includes('"presence_state"')) { st.presenceBytes += data.length; st.lastPresenceAt = now; return; }
    let msg;
    try { msg = JSON.parse(text); } catch { st.other++; return; }
    const [joinRef, ref, t, event, payload] = msg;
    if (event === 'phx_reply' && t === topic && ref === '1' && s.onJoin) {
      const cb = s.onJoin; s.onJoin = null; cb(payload);
    } else if (event === 'phx_reply' && t === 'phoenix') {
      st.heartbeatReplies++;
    } else {
      st.other++;
      if (st.errorSamples.length < 3 && (event === 'phx_error' || event === 'phx_close' || payload?.status === 'error')) {
        st.errorSamples.push(`${event} ${t} ${JSON.stringify(payload).slice(0, 200)}`);
      }
    }
    void joinRef;
  }

  function connect(s) {
    return new Promise((resolve) => {
      const t0 = performance.now();
      const ws = new WebSocket(s.url, { perMessageDeflate: false, handshakeTimeout: 30_000 });
      s.ws = ws;
      let done = false;
      ws.on('open', () => { done = true; s.open = true; resolve({ ok: true, ms: performance.now() - t0 }); });
      ws.on('message', (data, isBinary) => onMessage(s, data, isBinary));
      ws.on('error', (e) => {
        st.errorCount++;
        if (st.errorSamples.length < 3) st.errorSamples.push(`obs${s.k}: ${e.message}`);
        if (!done) { done = true; resolve({ ok: false, error: e.message }); }
      });
      ws.on('close', (code) => {
        const wasOpen = s.open;
        s.open = false;
        clearInterval(s.hbTimer);
        if (measuring && wasOpen && !s.closing) { st.closedDuring++; st.closeCodes.push(code); }
        if (s.onJoin) { const cb = s.onJoin; s.onJoin = null; cb({ status: 'closed', response: { code } }); }
        if (s.onClose) s.onClose(code);
        if (!done) { done = true; resolve({ ok: false, error: `closed ${code}` }); }
      });
    });
  }

  function join(s) {
    return new Promise((resolve) => {
      const t0 = performance.now();
      const timer = setTimeout(() => { s.onJoin = null; resolve({ ok: false, error: 'join timeout (30 s)' }); }, 30_000);
      s.onJoin = (payload) => {
        clearTimeout(timer);
        if (payload?.status === 'ok') {
          s.joined = true;
          // the phoenix client heartbeats every 30 s; stagger so they don't all fire together
          s.hbTimer = setTimeout(function beat() {
            if (!s.open) return;
            s.ws.send(JSON.stringify([null, `h${++s.hbRef}`, 'phoenix', 'heartbeat', {}]));
            s.hbTimer = setTimeout(beat, HEARTBEAT_PERIOD);
          }, Math.random() * HEARTBEAT_PERIOD);
          resolve({ ok: true, ms: performance.now() - t0 });
        } else {
          resolve({ ok: false, error: `join ${JSON.stringify(payload).slice(0, 200)}` });
        }
      };
      s.ws.send(JOIN);
    });
  }

  // Runs fn over items with at most `window` in flight.
  async function windowed(items, fn) {
    const results = new Array(items.length);
    let next = 0;
    const lane = async () => { while (next < items.length) { const i = next++; results[i] = await fn(items[i]); } };
    await Promise.all(Array.from({ length: Math.min(window, items.length) }, lane));
    return results;
  }

  const summary = (rs, key) => ({
    ok: rs.filter((r) => r.ok).length,
    [key]: rs.filter((r) => r.ok).map((r) => r.ms),
    errors: [...new Set(rs.filter((r) => !r.ok).map((r) => r.error))],
  });

  parentPort.on('message', async ({ id, cmd, start, end }) => {
    const reply = (m) => parentPort.postMessage({ id, ...m });
    switch (cmd) {
      case 'ping': return reply({});
      case 'connect': return reply(summary(await windowed(socks, connect), 'handshakes'));
      case 'join': {
        const rs = await windowed(socks.filter((s) => s.open), join);
        return reply(summary(rs, 'latencies'));
      }
      case 'poll': return reply({ lastPresenceAt: st.lastPresenceAt, presenceDiffs: st.presenceDiffs, presenceBytes: st.presenceBytes });
      case 'measure': {
        for (const k of ['presenceDiffs', 'presenceBytes', 'heartbeatReplies', 'other', 'errorCount']) st[k] = 0;
        st.errorSamples = [];
        for (const s of socks) s.telemetry = 0;
        nLat = 0; mStart = start; mEnd = end; measuring = true;
        probe = socks.find((s) => s.joined && s.open) ?? null; ticks = [];
        loop.reset(); loop.enable();
        return reply({});
      }
      case 'stop': {
        measuring = false; loop.disable();
        const latencies = lat.slice(0, nLat).buffer;
        const ms = (ns) => ns / 1e6;
        return parentPort.postMessage({
          id, telemetry: nLat, latencies, ticks,
          perSocket: socks.filter((s) => s.joined).map((s) => s.telemetry),
          presenceDiffs: st.presenceDiffs, heartbeatReplies: st.heartbeatReplies, other: st.other,
          closedDuring: st.closedDuring, closeCodes: st.closeCodes,
          errorCount: st.errorCount, errorSamples: st.errorSamples,
          loopDelay: { p50: ms(loop.percentile(50)) - LOOP_RES_MS, p99: ms(loop.percentile(99)) - LOOP_RES_MS, max: ms(loop.max) - LOOP_RES_MS },
        }, [latencies]);
      }
      case 'close': {
        const open = socks.filter((s) => s.open);
        let clean = 0; let forced = 0; const codes = [];
        await Promise.all(open.map((s) => new Promise((resolve) => {
          s.closing = true;
          const timer = setTimeout(() => { forced++; s.ws.terminate(); resolve(); }, 20_000);
          s.onClose = (code) => {
            clearTimeout(timer); codes.push(code);
            if (code === 1000 && s.ws._closeFrameReceived) clean++;
            resolve();
          };
          clearTimeout(s.hbTimer);
          s.ws.close(1000, 'bench done');
        })));
        return reply({ clean, forced, codes });
      }
      default: return reply({ error: `unknown command ${cmd}` });
    }
  });
}
