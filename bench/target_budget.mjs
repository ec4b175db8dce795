// Client of bench/target_budget (which starts the node with the board's limits and this script
// on the other cores). Measures, against one node:
//   * idle: RSS and erlang:memory() with the vehicle and no connection;
//   * then a pilot joins, takes the helm and sends thrust at BUDGET_THRUST_HZ (+ heartbeat every
//     100 ms), and observers join in steps (BUDGET_STEPS). At each step, after BUDGET_SETTLE s:
//     RSS and erlang:memory() (total, processes, binary, ets) and their growth per observer
//     since the step with none; then for BUDGET_SECONDS: telemetry delivery latency (observer
//     arrival - payload.sent_at, every frame of every observer), frames delivered against the
//     broadcasts (the pilot's socket sees every broadcast: each observer must get the same
//     sent_at values in the window), and the pilot's control latency (thrust -> phx_reply).
//   * where the memory is at the largest step: the process groups holding the most.
// Prints figures, asserts nothing.
//
// Environment: BUDGET_URL, BUDGET_SERVER_PID, BUDGET_STEPS, BUDGET_RELEASE (bin/neptunus rpc
// for erlang:memory(); RELEASE_NODE set by the caller), BUDGET_SECONDS (20), BUDGET_SETTLE (5),
// BUDGET_THRUST_HZ (10), BUDGET_WORKERS (2), BUDGET_WINDOW (100 joins in flight), BUDGET_MARK
// (what every figure is marked with: whose CPU it was measured on).

import { createRequire } from 'node:module';
import { Worker, isMainThread, parentPort, workerData } from 'node:worker_threads';
import { readFileSync } from 'node:fs';
import { execFile } from 'node:child_process';
import { fileURLToPath } from 'node:url';
import { performance } from 'node:perf_hooks';
import path from 'node:path';
import { channelsSocket } from './support/channels.mjs';
import { BINS, histPct, pct } from './support/stats.mjs';

const require = createRequire(new URL('../assets/package.json', import.meta.url));
const WebSocket = require('ws');
const nowMs = () => performance.timeOrigin + performance.now();
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const num = (v, d) => { const n = Number(v ?? ''); return Number.isFinite(n) && n >= 0 && v !== '' && v != null ? n : d; };

const URL_BASE = process.env.BUDGET_URL ?? 'ws://127.0.0.1:4214';
const TOPIC = 'vehicle:rov';
const wsUrl = (name) => `${URL_BASE}/socket/websocket?vsn=2.0.0&name=${name}`;
const MARK = process.env.BUDGET_MARK || '[this CPU]';

const f1 = (x) => (Number.isFinite(x) ? x.toFixed(1) : 'n/a');
const f0 = (x) => (Number.isFinite(x) ? x.toFixed(0) : 'n/a');

// erlang:memory() and the largest process groups, from the node itself (bin/neptunus rpc).
const PROBE = `
m = :erlang.memory()
groups =
  Enum.reduce(Process.list(), %{}, fn p, acc ->
    case Process.info(p, [:memory, :dictionary, :initial_call, :registered_name]) do
      nil -> acc
      info ->
        label =
          case info[:registered_name] do
            [] ->
              case Keyword.get(info[:dictionary], :"$initial_call", info[:initial_call]) do
                {mod, f, a} -> "#{inspect(mod)}.#{f}/#{a}"
                other -> inspect(other)
              end
            name -> inspect(name)
          end
        Map.update(acc, label, {1, info[:memory]}, fn {n, b} -> {n + 1, b + info[:memory]} end)
    end
  end)
top = groups |> Enum.sort_by(fn {_, {_, b}} -> -b end) |> Enum.take(6) |> Enum.map(fn {l, {n, b}} -> %{label: l, count: n, bytes: b} end)
IO.write(:jiffy.encode(%{total: m[:total], processes: m[:processes], binary: m[:binary], ets: m[:ets], atom: m[:atom], code: m[:code], procs: length(Process.list()), ports: length(:erlang.ports()), top: top}))
`;

function probe() {
  const bin = path.join(process.env.BUDGET_RELEASE ?? '', 'bin/neptunus');
  return new Promise((resolve) => {
    execFile(bin, ['rpc', PROBE], { timeout: 60_000 }, (err, stdout) => {
      if (err) return resolve({ error: String(err.message).split('\n')[0] });
      try { resolve(JSON.parse(stdout.trim())); } catch { resolve({ error: stdout.slice(0, 200) }); }
    });
  });
}

async function main() {
  const STEPS = (process.env.BUDGET_STEPS ?? '0,250,500,1000,1500,2000').split(',').map(Number).sort((a, b) => a - b);
  const SECONDS = num(process.env.BUDGET_SECONDS, 20);
  const SETTLE = num(process.env.BUDGET_SETTLE, 5);
  const THRUST_HZ = num(process.env.BUDGET_THRUST_HZ, 10) || 10;
  const WORKERS = Math.max(1, Math.floor(num(process.env.BUDGET_WORKERS, 2)));
  const WINDOW = Math.max(1, Math.floor(num(process.env.BUDGET_WINDOW, 100)));
  const PID = Number(process.env.BUDGET_SERVER_PID ?? 0);
  const rssKb = () => {
    try { return Number(/VmRSS:\s+(\d+)/.exec(readFileSync(`/proc/${PID}/status`, 'utf8'))[1]); } catch { return NaN; }
  };
  const alive = () => { try { process.kill(PID, 0); return true; } catch { return false; } };

  // idle: the vehicle, no connection
  await sleep(SETTLE * 1000);
  const idle = { rss: rssKb(), mem: await probe() };
  console.log(`idle, one vehicle (sitl), no connection: RSS ${f1(idle.rss / 1024)} MiB, erlang:memory total ` +
    `${f1(idle.mem.total / 1048576)} MiB (processes ${f1(idle.mem.processes / 1048576)}, binary ${f1(idle.mem.binary / 1048576)}, ` +
    `ets ${f1(idle.mem.ets / 1048576)}, code ${f1(idle.mem.code / 1048576)}), ${idle.mem.procs} processes ${MARK}`);

  // the pilot
  const pilot = await channelsSocket(WebSocket, wsUrl('budgetpilot'), {
    onClosed: (code) => console.error(`pilot socket closed by the server (${code})`),
  });
  const join = await pilot.push(TOPIC, 'phx_join', {});
  if (join.status !== 'ok') throw new Error(`pilot join: ${JSON.stringify(join.response)}`);
  const grant = await pilot.push(TOPIC, 'request_control', {});
  if (grant.status !== 'ok' || grant.response.status !== 'granted') throw new Error(`request_control: ${JSON.stringify(grant)}`);
  let epoch = grant.response.grant.epoch;
  let broadcasts = [], replies = [], cmdErrors = 0, stops = 0;
  pilot.onEvent = (event, payload) => {
    if ((event === 'control_granted' || event === 'helm') && payload.epoch != null) epoch = payload.epoch;
    else if (event === 'stopped') stops++;
    else if (event === 'telemetry' && payload.sent_at != null) broadcasts.push(payload.sent_at);
  };
  const heartbeat = setInterval(() => { pilot.push(TOPIC, 'heartbeat', {}).catch(() => {}); }, 100);
  let i = 0;
  const thrust = setInterval(() => {
    i++;
    const sent = performance.now();
    pilot.push(TOPIC, 'thrust', { mode: 'motion', surge: ((i % 40) + 1) / 50, heave: 0, yaw: 0, epoch }).then((r) => {
      if (r.status !== 'ok') cmdErrors++;
      replies.push(performance.now() - sent);
    });
  }, 1000 / THRUST_HZ);

  // observers, spread over worker threads
  const workers = [];
  for (let w = 0; w < WORKERS; w++) {
    const worker = new Worker(fileURLToPath(import.meta.url), { workerData: { window: Math.max(1, Math.floor(WINDOW / WORKERS)) } });
    worker.on('error', (e) => { console.error('observer worker crashed:', e); process.exit(2); });
    workers.push(worker);
  }
  let seq = 0;
  const ask = (worker, msg) => new Promise((resolve) => {
    const id = ++seq;
    const on = (m) => { if (m.id === id) { worker.off('message', on); resolve(m); } };
    worker.on('message', on); worker.postMessage({ id, ...msg });
  });
  const askAll = (msg) => Promise.all(workers.map((w) => ask(w, msg)));

  console.log(`# pilot: thrust ${THRUST_HZ} Hz + heartbeat 10 Hz; observers join in steps ${STEPS.join(', ')}; ` +
    `${SETTLE} s settle, then ${SECONDS} s measured per step; delivery = observer arrival - sent_at; control = thrust -> reply`);
  const header = ['observers', 'RSS MiB', 'RSS/obs KiB', 'BEAM MiB', 'BEAM/obs KiB', 'processes MiB', 'binary MiB',
    'delivery p50/p99 ms', 'frames delivered/broadcast', 'control p50/p99 ms', 'closed by server'];
  console.log(header.join(' | ') + ' | ' + MARK);
  const rows = [];
  let base = null, joined = 0, lastMem = null;
  for (const step of STEPS) {
    // open observers up to `step`, spread over the workers
    const want = step - joined;
    if (want > 0) {
      const per = workers.map((_, w) => Math.floor(want / WORKERS) + (w < want % WORKERS ? 1 : 0));
      const opened = await Promise.all(workers.map((w, k) => ask(w, { cmd: 'open', n: per[k], from: joined + per.slice(0, k).reduce((a, b) => a + b, 0) })));
      joined += opened.reduce((a, r) => a + r.joined, 0);
    }
    await sleep(SETTLE * 1000);
    const mem = await probe();
    const rss = rssKb();
    lastMem = mem;
    if (base === null) base = { n: joined, rss, mem };
    // the measured window
    await askAll({ cmd: 'reset' });
    broadcasts = []; replies = [];
    const from = nowMs();
    await sleep(SECONDS * 1000);
    const to = nowMs() - 1000; // frames broadcast in the last second may still be on their way
    await sleep(500);
    const obs = await askAll({ cmd: 'take', from, to });
    const expected = broadcasts.filter((t) => t >= from && t <= to).length;
    const hist = new Float64Array(BINS + 1);
    for (const o of obs) for (let b = 0; b <= BINS; b++) hist[b] += o.hist[b];
    const counts = obs.flatMap((o) => o.counts);
    const missing = counts.reduce((a, c) => a + Math.max(0, expected - c), 0);
    const closed = obs.reduce((a, o) => a + o.closedByServer, 0);
    const dn = joined - base.n;
    const row = {
      n: joined, rss: rss / 1024, beam: mem.total / 1048576,
      rssPer: dn > 0 ? (rss - base.rss) / dn : NaN, beamPer: dn > 0 ? (mem.total - base.mem.total) / 1024 / dn : NaN,
      procMem: mem.processes / 1048576, bin: mem.binary / 1048576,
      d50: histPct(hist, 50), d99: histPct(hist, 99), missing, expected, delivered: counts.reduce((a, c) => a + Math.min(c, expected), 0),
      c50: pct(replies, 50), c99: pct(replies, 99), closed,
    };
    rows.push(row);
    console.log([row.n, f1(row.rss), f1(row.rssPer), f1(row.beam), f1(row.beamPer), f1(row.procMem), f1(row.bin),
      `${f1(row.d50)}/${f1(row.d99)}`, `${row.delivered}/${row.expected * row.n}${row.missing ? ` (${row.missing} missing)` : ''}`,
      `${f1(row.c50)}/${f1(row.c99)}`, row.closed].join(' | ') + ' | ' + MARK);
    if (!alive()) { console.log('# the node died at this step'); break; }
  }
  clearInterval(thrust);
  clearInterval(heartbeat);

  const ok = rows.filter((r) => r.n > 0 && r.d99 < 50 && r.missing === 0 && r.closed === 0);
  const best = ok.length ? ok[ok.length - 1] : null;
  console.log(best
    ? `# one core serves ${best.n} observers at 20 Hz with delivery p99 ${f1(best.d99)} ms < 50 ms and every frame delivered; ` +
      `the pilot's control latency there: p50 ${f1(best.c50)} ms, p99 ${f1(best.c99)} ms ${MARK} (largest step measured that passes; steps tried: ${rows.map((r) => r.n).join(', ')})`
    : `# no step with observers met delivery p99 < 50 ms and every frame delivered ${MARK}`);
  const last = rows[rows.length - 1];
  if (last && last.n > base.n) {
    console.log(`# memory per observer (${base.n} -> ${last.n}): RSS ${f1(last.rssPer)} KiB, erlang:memory(total) ${f1(last.beamPer)} KiB ${MARK}`);
  }
  if (lastMem?.top) {
    console.log(`# the largest process groups at ${last?.n ?? 0} observers (name or initial call: count, total, per process):`);
    for (const g of lastMem.top) console.log(`#   ${g.label}: ${g.count}, ${f1(g.bytes / 1048576)} MiB, ${f0(g.bytes / g.count / 1024)} KiB`);
    console.log(`#   erlang:memory: processes ${f1(lastMem.processes / 1048576)} MiB, binary ${f1(lastMem.binary / 1048576)} MiB, ets ${f1(lastMem.ets / 1048576)} MiB, ${lastMem.ports} ports`);
  }
  console.log(`# pilot: ${stops} stopped events, ${cmdErrors} command errors`);
  await askAll({ cmd: 'close' });
  pilot.close();
  await Promise.all(workers.map((w) => w.terminate()));
  process.exit(0);
}

// A worker thread of observers: opens sockets on request, records every telemetry frame's
// delivery latency and its sent_at per socket until asked ('take').
function observers({ window }) {
  const sockets = [];
  let hist = new Uint32Array(BINS + 1);
  let closedByServer = 0;
  const prefix = `[null,null,${JSON.stringify(TOPIC)},"telemetry",`;
  const openOne = (k) => new Promise((resolve) => {
    const ws = new WebSocket(wsUrl(`obs${k}`), { perMessageDeflate: false });
    const entry = { ws, seen: [] };
    let joined = false;
    ws.on('message', (data) => {
      const text = data.toString();
      if (text.startsWith(prefix)) {
        const m = /"sent_at":([0-9.e+]+)/.exec(text);
        if (m) {
          const sent = Number(m[1]);
          entry.seen.push(sent);
          hist[Math.min(BINS, Math.max(0, Math.floor((nowMs() - sent) * 10)))]++;
        }
      } else if (!joined && text.startsWith('["j","j"')) { joined = true; resolve(text.includes('"status":"ok"')); }
    });
    ws.once('open', () => ws.send(JSON.stringify(['j', 'j', TOPIC, 'phx_join', {}])));
    ws.once('error', () => resolve(false));
    ws.on('close', () => { if (!ws.closing) closedByServer++; if (!joined) resolve(false); });
    sockets.push(entry);
    setInterval(() => { if (ws.readyState === 1) ws.send(JSON.stringify([null, 'hb', 'phoenix', 'heartbeat', {}])); }, 30000).unref();
  });
  parentPort.on('message', async ({ id, cmd, n, from, to }) => {
    if (cmd === 'open') {
      let next = 0, joined = 0;
      await Promise.all(Array.from({ length: Math.min(window, n) }, async () => {
        while (next < n) { if (await openOne(from + next++)) joined++; }
      }));
      parentPort.postMessage({ id, joined });
    } else if (cmd === 'reset') {
      hist = new Uint32Array(BINS + 1);
      for (const s of sockets) s.seen = [];
      parentPort.postMessage({ id });
    } else if (cmd === 'take') {
      const counts = sockets.map((s) => s.seen.filter((t) => t >= from && t <= to).length);
      parentPort.postMessage({ id, hist, counts, closedByServer });
    } else if (cmd === 'close') {
      for (const s of sockets) { s.ws.closing = true; s.ws.close(1000); }
      await sleep(500);
      parentPort.postMessage({ id });
    }
  });
}

if (isMainThread) await main(); else observers(workerData);
