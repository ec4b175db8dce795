// Control latency benchmark client: pilot command over the WebSocket → go(...) bytes read on
// the far side of the board's serial line (a pty). Prints figures, asserts nothing.
// Started by bench/control_latency, which starts the server once this process has created the
// board's pty (LAT_LINK) and writes the server's OS pid to LAT_SERVER_PID_FILE when it answers:
//
//   LAT_URL=ws://127.0.0.1:4211 LAT_LINK=/tmp/x/board LAT_SERVER_PID_FILE=/tmp/x/server.pid \
//     node bench/control_latency.mjs [OBSERVERS] [SAMPLES]
//
// OBSERVERS is a comma-separated list of observer counts, measured in turn (default "0,1000");
// SAMPLES is the number of commands per measurement (default 1000).
//
// This process is the pilot and the board on the other end of the pty. The pty is created by the
// server's own port program in pty mode (priv/neptunus_uart pty LINK, as for a SITL board),
// which this process runs and speaks to in its {packet, 2} frames: 'w' DATA to write to the
// line, 'r' DATA for bytes read from it. So the bytes cross one pty, as from a real UART's
// driver to the board, and no relay (socat) sits in the measured path. The go(...) bytes are
// timed where they are read, on the pty's master end: the port program runs with
// NEPTUNUS_UART_RX_STAMPS=1 and sends the CLOCK_MONOTONIC time of each read (a 't' frame),
// the clock of process.hrtime here. The time they reach this process, one pipe hop later, is
// printed too. The board's port program asks for the same short OS time slice as the
// server's (NEPTUNUS_SLICE_NS; LAT_BOARD_SLICE_US, default 100, or "default"). It sends telemetry
// lines like an OpenROV board (navigation data at 50 Hz, status at 10 Hz) so the vehicle
// publishes telemetry to every observer at 20 Hz while we measure, and it reads the go(...)
// commands the server writes. The observers' sockets live in a separate OS process (this
// script again, started with LAT_ROLE=observers and run under `nice -n LAT_OBSERVER_NICE`),
// so their 20 000 messages/s neither share this process' event loop nor its threads; in
// reality they are browsers on other machines.
//
// Environment: LAT_URL (ws://127.0.0.1:4211), LAT_LINK and LAT_SERVER_PID_FILE (required),
// LAT_DONE_FILE (written when the figures are out; then this process waits for SIGTERM),
// LAT_VEHICLE (rov), LAT_UART (priv/neptunus_uart), LAT_CLK_TCK (100), LAT_WINDOW (100 joins in flight),
// LAT_BOARD_SLICE_US (100), LAT_OBSERVER_NICE (0: the observer process' nice value, 0..19), LAT_OBSERVER_CPUS (unset: any
// CPU; e.g. "1": the observer process runs on those CPUs only, see bench/README.md),
// LAT_BOARD_RT (unset; N: the board's port program — where the go(...) bytes are timed — runs
// SCHED_FIFO N, as root: see bench/cluster).

import { createRequire } from 'node:module';
import { spawn } from 'node:child_process';
import { existsSync, readFileSync, writeFileSync } from 'node:fs';
import os from 'node:os';
import { fileURLToPath } from 'node:url';
import { performance, monitorEventLoopDelay } from 'node:perf_hooks';
import dgram from 'node:dgram';
import { channelsSocket } from './support/channels.mjs';
import { commandLong, frames, heartbeat as mavHeartbeat, manualControl } from './support/mavlink.mjs';

const [GAP_MIN, GAP_MAX] = gap();
const require = createRequire(new URL('../assets/package.json', import.meta.url));
const WebSocket = require('ws');

const URL_BASE = process.env.LAT_URL ?? 'ws://127.0.0.1:4211';
const VEHICLE = process.env.LAT_VEHICLE ?? 'rov';
const TOPIC = `vehicle:${VEHICLE}`;
const wsUrl = (name, base = URL_BASE) => `${base}/socket/websocket?vsn=2.0.0&name=${encodeURIComponent(name)}`;
// LAT_OBSERVER_URL: the observers connect to another node of the fleet (bench/cluster)
const OBSERVER_URL_BASE = process.env.LAT_OBSERVER_URL ?? URL_BASE;
// LAT_GCS_PORT (bench/gcs_latency): the pilot is a MAVLink ground station on the node's udpin
// endpoint at this port (MANUAL_CONTROL instead of thrust), and the observers are ground
// stations watching (each its own UDP socket, a session of its own)
const GCS_PORT = process.env.LAT_GCS_PORT ? Number(process.env.LAT_GCS_PORT) : null;
const GCS_SYSID = 1; // the vehicle's MAVLink system id (the node's only vehicle)
const WINDOW = Number(process.env.LAT_WINDOW ?? 100); // observers opening at once
// an observer not joined (a ground station: not answered) within this counts as not joined
const OBSERVER_OPEN_MS = 30_000;

if (process.env.LAT_ROLE === 'observers') {
  await observers();
} else {
  // a failure (the observer process gone, no answer from it) is said, and the exit status
  // tells bench/control_latency: never a wait without end
  await main().catch((err) => {
    console.error(`control_latency: ${err.message}`);
    process.exit(1);
  });
}

// ---------------------------------------------------------------------------------------

async function main() {
  const counts = (process.argv[2] ?? process.env.LAT_OBSERVERS ?? (GCS_PORT ? '0,10' : '0,1000')).split(',').map(Number);
  const SAMPLES = Number(process.argv[3] ?? process.env.LAT_SAMPLES ?? 1000);
  // LAT_CLIENT_NICE: this process (the instrument: the pilot's machine and the board) and its
  // port program at another OS priority, e.g. -10 (root only). The server keeps its own.
  if (process.env.LAT_CLIENT_NICE) os.setPriority(0, Number(process.env.LAT_CLIENT_NICE));
  const LINK = process.env.LAT_LINK;
  const PID_FILE = process.env.LAT_SERVER_PID_FILE;
  const UART = process.env.LAT_UART ?? fileURLToPath(new URL('../priv/neptunus_uart', import.meta.url));
  const CLK_TCK = Number(process.env.LAT_CLK_TCK ?? 100);
  if (!LINK || !PID_FILE) throw new Error('LAT_LINK and LAT_SERVER_PID_FILE are required');

  const out = (label, value) => console.log(`${(label + ':').padEnd(46)} ${value}`);
  const OBSERVER_NICE = Number(process.env.LAT_OBSERVER_NICE ?? 0);
  // utime + stime of a process (all its threads), in clock ticks
  const cpuTicks = (pid) => {
    if (!pid) return null;
    try {
      const s = readFileSync(`/proc/${pid}/stat`, 'utf8');
      const f = s.slice(s.lastIndexOf(')') + 2).split(' ');
      return Number(f[11]) + Number(f[12]);
    } catch { return null; }
  };
  // whole machine: [busy, total] ticks, and CPU pressure (some, total µs)
  const machine = () => {
    const f = readFileSync('/proc/stat', 'utf8').split('\n')[0].trim().split(/\s+/).slice(1).map(Number);
    const total = f.reduce((a, b) => a + b, 0);
    const idle = f[3] + f[4];
    let pressure = null;
    try {
      const m = /some avg10=\S+ avg60=\S+ avg300=\S+ total=(\d+)/.exec(readFileSync('/proc/pressure/cpu', 'utf8'));
      if (m) pressure = Number(m[1]);
    } catch { /* no PSI */ }
    return { busy: total - idle, total, pressure };
  };

  // The board's end of the line: the port program on the pty's master end.
  const board = uartPty(UART, LINK);
  await board.opened;
  let rx = '';
  let waiter = null; // {expect, resolve}
  let goLines = 0;
  board.onData = (chunk, readNs) => {
    const now = performance.now();
    rx += chunk.toString('latin1');
    let i;
    while ((i = rx.indexOf(';')) >= 0) {
      const cmd = rx.slice(0, i + 1);
      rx = rx.slice(i + 1);
      // echoed as the firmware does: the board link confirms the motor modifiers by it and
      // holds thrust at neutral until they are (docs/OPENROV.md, Settings)
      if (/^[a-z0-9]+\([-0-9,]*\);$/.test(cmd)) board.write(`cmd:${cmd}\r\n`);
      if (cmd.startsWith('go(')) {
        goLines++;
        if (waiter && cmd === waiter.expect) { const w = waiter; waiter = null; w.resolve({ now, readNs }); }
      }
    }
  };

  // The server starts now; its OS pid arrives when it answers.
  while (!existsSync(PID_FILE)) await sleep(100);
  const SERVER_PID = Number(readFileSync(PID_FILE, 'utf8').trim()) || 0;

  // Telemetry like an OpenROV board.
  let tick = 0;
  const telemetry = setInterval(() => {
    tick++;
    const hdg = (tick * 0.5) % 360;
    let text = `hdgd:${hdg.toFixed(2)};deap:1.000;pitc:0.00;roll:0.00;yaw:0.00;fthr:0;\r\n`;
    if (tick % 5 === 0) text += 'vout:12.10;iout:0.50;time:1000;pres:1113.80;temp:10.0;\r\n';
    board.write(text);
  }, 20);

  // The pilot: a browser's connection, or a ground station (LAT_GCS_PORT).
  const pilot = GCS_PORT ? await gcsPilot(GCS_PORT) : await browserPilot();
  const heartbeat = setInterval(() => pilot.heartbeat(), 100);

  // The observers: a separate OS process (this script, LAT_ROLE=observers), under nice.
  const script = fileURLToPath(import.meta.url);
  let closing = false;
  // nice -n is relative to our own nice value
  const niced = ['nice', '-n', String(OBSERVER_NICE - os.getPriority()), process.execPath, script];
  // LAT_OBSERVER_CPUS: the observers' process on these CPUs only (taskset), standing for
  // browsers on other machines
  const OBSERVER_CPUS = process.env.LAT_OBSERVER_CPUS;
  const argv = OBSERVER_CPUS ? ['taskset', '-c', OBSERVER_CPUS, ...niced] : niced;
  const worker = spawn(argv[0], argv.slice(1), {
    stdio: ['ignore', 'inherit', 'inherit', 'ipc'],
    env: { ...process.env, LAT_ROLE: 'observers' },
  });
  // The observer process' end, however it comes (an exit, or an error that kept it from
  // running or from being spoken to): no wait for its answers outlives it.
  const workerEnded = new Promise((resolve) => {
    worker.once('exit', (code, signal) => resolve({ code, why: `exited (${signal ?? `status ${code}`})` }));
    worker.once('error', (err) => resolve({ code: null, why: `failed (${err.message})` }));
  });
  workerEnded.then(({ why }) => {
    if (!closing) { console.error(`control_latency: the observer process ${why} during the run`); process.exit(1); }
  });
  // The next message of this type from the observer process; rejects when the process ends
  // first (one that says 'closed' and exits 0 may be seen exiting before its message is read)
  // or after `timeoutMs`.
  const fromWorker = (type, timeoutMs) => new Promise((resolve, reject) => {
    let timer = null;
    const settle = (f, v) => { worker.off('message', h); clearTimeout(timer); f(v); };
    const h = (m) => { if (m.type === type) settle(resolve, m); };
    worker.on('message', h);
    timer = setTimeout(() => settle(reject, new Error(`no '${type}' from the observer process within ${timeoutMs / 1000} s`)), timeoutMs);
    workerEnded.then(({ code, why }) => {
      if (type === 'closed' && code === 0) settle(resolve, { type });
      else settle(reject, new Error(`the observer process ${why} before its '${type}'`));
    });
  });
  let observing = 0;

  console.log(GCS_PORT
    ? `# control latency: a ground station's MANUAL_CONTROL (UDP to 127.0.0.1:${GCS_PORT}) -> go(...) bytes on the pty's master end (${LINK} -> ${board.slave}); observers are ground stations watching`
    : `# control latency: pilot thrust over the WebSocket -> go(...) bytes on the pty's master end (${LINK} -> ${board.slave})`);
  console.log(`# ${SAMPLES} commands per run, vehicle ${VEHICLE}, server ${URL_BASE}`);
  console.log(`# observers: a separate node process (os pid ${worker.pid}) at nice ${OBSERVER_NICE}` +
    `${OBSERVER_CPUS ? ` on CPUs ${OBSERVER_CPUS}` : ''}; ` +
    `pilot + board: this process (os pid ${process.pid}) at nice ${os.getPriority()}` +
    (process.env.LAT_BOARD_RT ? `, the board's port program real-time (SCHED_FIFO ${process.env.LAT_BOARD_RT}, LAT_BOARD_RT)` : ''));
  console.log(`# load average at start: ${os.loadavg().map((x) => x.toFixed(2)).join(' ')}`);

  for (const n of counts) {
    if (n > observing) {
      worker.send({ type: 'open', count: n - observing });
      // each observer gets OBSERVER_OPEN_MS to join (or counts as not joined), WINDOW at a time
      const m = await fromWorker('opened', (Math.ceil((n - observing) / WINDOW) + 1) * OBSERVER_OPEN_MS);
      observing = m.joined;
      await sleep(2000); // let the presence traffic of the joins settle
    }

    worker.send({ type: 'count' });
    const before = await fromWorker('counted', 30_000);
    const cpu0 = cpuTicks(SERVER_PID), obs0 = cpuTicks(worker.pid), self0 = process.cpuUsage();
    const m0 = machine();
    const t0 = performance.now();
    const loop = monitorEventLoopDelay({ resolution: 1 });
    loop.enable();

    const toGo = [], toGoHere = [], toReply = [];
    let timeouts = 0, errors = 0, lastError = '';
    for (let i = 0; i < SAMPLES; i++) {
      const s = ((i % 40) + 1) / 50; // 0.02 .. 0.80, consecutive commands always differ
      const portUs = Math.round(1500 - 250 * s); // gain 0.5, port reversed (thesis wiring)
      const stbdUs = Math.round(1500 + 250 * s);
      const expect = `go(${portUs},1500,${stbdUs},1);`;
      const arrived = new Promise((resolve) => { waiter = { expect, resolve }; });
      const sent = performance.now();
      const sentNs = process.hrtime.bigint(); // CLOCK_MONOTONIC, as the port program's stamps
      const reply = pilot.thrust(s)?.then((r) => {
        if (r.status !== 'ok') { errors++; lastError = JSON.stringify(r.response); }
        toReply.push(performance.now() - sent);
      });
      const got = await Promise.race([arrived, sleep(1000).then(() => null)]);
      if (got == null) { timeouts++; waiter = null; } else {
        if (got.readNs == null) throw new Error('no read time from the port program: rebuild it (mix compile)');
        toGo.push(Number(got.readNs - sentNs) / 1e6);
        toGoHere.push(got.now - sent);
      }
      await reply;
      await sleep(GAP_MIN + Math.random() * (GAP_MAX - GAP_MIN));
    }

    loop.disable();
    const secs = (performance.now() - t0) / 1000;
    const cpu1 = cpuTicks(SERVER_PID), obs1 = cpuTicks(worker.pid), self1 = process.cpuUsage(self0);
    const m1 = machine();
    worker.send({ type: 'count' });
    const after = await fromWorker('counted', 30_000);

    console.log(`\n## ${observing} observers`);
    out('observers joined', observing);
    out('commands / go lines matched / timeouts', `${SAMPLES} / ${toGo.length} / ${timeouts}`);
    out('command errors', errors ? `${errors} (last: ${lastError})` : 0);
    out('command -> go bytes  p50 / p90 / p99 / max', stats(toGo));
    out('  the same, at this process (+ a pipe hop)', stats(toGoHere));
    out('command -> reply     p50 / p90 / p99 / max', GCS_PORT ? 'n/a (MANUAL_CONTROL has no reply)' : stats(toReply));
    out('client event-loop delay p50 / p99', `${(loop.percentile(50) / 1e6).toFixed(2)} / ${(loop.percentile(99) / 1e6).toFixed(2)} ms`);
    out(GCS_PORT ? 'MAVLink frames received by observers' : 'telemetry received by observers',
      `${after.messages - before.messages} (${((after.messages - before.messages) / secs).toFixed(0)}/s)`);
    const pct = (ticks) => `${(ticks / CLK_TCK / secs * 100).toFixed(1)} %`;
    out('CPU (% of one core): server / pilot+board / observers',
      `${cpu0 != null && cpu1 != null ? pct(cpu1 - cpu0) : 'n/a'} / ` +
      `${((self1.user + self1.system) / 1e4 / secs).toFixed(1)} % / ` +
      `${obs0 != null && obs1 != null ? pct(obs1 - obs0) : 'n/a'}`);
    const cores = os.cpus().length;
    const ours = (cpu1 ?? 0) - (cpu0 ?? 0) + (obs1 ?? 0) - (obs0 ?? 0) + (self1.user + self1.system) / 1e6 * CLK_TCK;
    out('machine CPU busy / CPU pressure (some)',
      `${((m1.busy - m0.busy) / (m1.total - m0.total) * 100).toFixed(0)} % of ${cores} cores / ` +
      (m0.pressure != null ? `${((m1.pressure - m0.pressure) / 1e4 / secs).toFixed(0)} %` : 'n/a'));
    out('  of which not server or client processes', `${pct(m1.busy - m0.busy - ours)} of one core ` +
      '(kernel softirq, the two port programs, other work on the machine)');
  }

  clearInterval(heartbeat);
  clearInterval(telemetry);
  closing = true;
  worker.send({ type: 'close' });
  await fromWorker('closed', 30_000);
  pilot.close();
  // Keep the pty until bench/control_latency has stopped the server (its end of the line would
  // otherwise hang up under it): say we are done and wait for SIGTERM.
  const DONE_FILE = process.env.LAT_DONE_FILE;
  if (DONE_FILE) {
    process.on('SIGTERM', () => { board.close(); process.exit(0); });
    writeFileSync(DONE_FILE, 'done\n');
    setInterval(() => {}, 60_000);
    return;
  }
  board.close();
  process.exit(0);
}

/** The pilot as a browser's connection: joined, granted the helm; thrust() resolves with the reply. */
async function browserPilot() {
  const socket = await connect('pilot');
  const join = await socket.push(TOPIC, 'phx_join', {});
  if (join.status !== 'ok') throw new Error(`join failed: ${JSON.stringify(join.response)}`);
  const grant = await socket.push(TOPIC, 'request_control', {});
  if (grant.status !== 'ok' || grant.response.status !== 'granted') {
    throw new Error(`request_control: ${JSON.stringify(grant)}`);
  }
  let epoch = grant.response.grant.epoch;
  socket.onEvent = (event, payload) => {
    if (event === 'control_granted' && payload.epoch != null) epoch = payload.epoch;
  };
  return {
    thrust: (s) => socket.push(TOPIC, 'thrust', { mode: 'motion', surge: s, heave: 0, yaw: 0, epoch }),
    heartbeat: () => socket.push(TOPIC, 'heartbeat', {}).catch(() => {}),
    close: () => socket.close(),
  };
}

/**
 * The pilot as a ground station on the node's udpin endpoint: it asks for the free helm
 * (MAV_CMD_REQUEST_OPERATOR_CONTROL, answered ACCEPTED), then thrust(s) sends MANUAL_CONTROL
 * x = 1000 s (no reply) and heartbeat() a HEARTBEAT (the deadman's feed, as a browser's).
 */
async function gcsPilot(port) {
  const sock = dgram.createSocket('udp4');
  // ECONNREFUSED while the endpoint is not up yet: the request below is tried again
  let lastError = 'none';
  sock.on('error', (err) => { lastError = err.message; });
  await new Promise((resolve, reject) => sock.connect(port, '127.0.0.1', (e) => (e ? reject(e) : resolve())));
  let seq = 0;
  const send = (build) => sock.send(build({ seq: seq++ }));
  let granted;
  const grant = new Promise((resolve) => { granted = resolve; });
  sock.on('message', (buf) => {
    for (const f of frames(buf, 3)) {
      // COMMAND_ACK of MAV_CMD_REQUEST_OPERATOR_CONTROL, MAV_RESULT_ACCEPTED
      if (f.id === 77 && f.payload.readUInt16LE(0) === 32100 && f.payload[2] === 0) granted();
    }
  });
  for (let tries = 0; ; tries++) {
    send((o) => mavHeartbeat(o));
    send((o) => commandLong(GCS_SYSID, 32100, [0, 1, 0, 10], o));
    if (await Promise.race([grant.then(() => true), sleep(1000).then(() => false)])) break;
    if (tries === 10) throw new Error(`no ACCEPTED answer to MAV_CMD_REQUEST_OPERATOR_CONTROL on udp 127.0.0.1:${port} (last socket error: ${lastError})`);
  }
  return {
    thrust: (s) => { send((o) => manualControl(GCS_SYSID, { x: Math.round(s * 1000) }, o)); return null; },
    heartbeat: () => send((o) => mavHeartbeat(o)),
    close: () => sock.close(),
  };
}

function stats(xs) {
  if (xs.length === 0) return 'n/a';
  const s = [...xs].sort((a, b) => a - b);
  const p = (q) => s[Math.min(s.length - 1, Math.floor(q * s.length))];
  return `${p(0.5).toFixed(3)} / ${p(0.9).toFixed(3)} / ${p(0.99).toFixed(3)} / ${s[s.length - 1].toFixed(3)} ms`;
}

function sleep(ms) { return new Promise((r) => setTimeout(r, ms)); }

// the pause after each command arrives, ms: LAT_GAP_MS "MIN-MAX" (default 5-15, ≈ 80 commands/s
// with the round trip; the board link paces the serial line to 60 bytes per 30 ms, ≈ 55 go()/s
// with pings: above that, go() commands wait their turn, and the figures show it)
function gap() {
  const m = /^(\d+(?:\.\d+)?)-(\d+(?:\.\d+)?)$/.exec(process.env.LAT_GAP_MS ?? '5-15');
  if (!m) throw new Error(`LAT_GAP_MS must be MIN-MAX in ms, got ${process.env.LAT_GAP_MS}`);
  return [Number(m[1]), Number(m[2])];
}

// The port program in pty mode: `opened` resolves when the pty exists (its 'o' frame),
// `write(text)` sends bytes to the line, `onData(buffer)` gets the bytes read from it.
function uartPty(program, link) {
  // NEPTUNUS_UART_RX_STAMPS: a 't' frame with the read's CLOCK_MONOTONIC time before each 'r'
  // frame; NEPTUNUS_SLICE_NS: the short time slice the server's own port program asks for
  const env = { ...process.env, NEPTUNUS_UART_RX_STAMPS: '1' };
  const sliceUs = process.env.LAT_BOARD_SLICE_US ?? '100';
  if (sliceUs === 'default') delete env.NEPTUNUS_SLICE_NS;
  else env.NEPTUNUS_SLICE_NS = String(Number(sliceUs) * 1000);
  // LAT_BOARD_RT=N: the board's port program real-time (chrt -f N; the caller checked it is
  // allowed): it stands for the board's microcontroller, which no load on the pilot's machine delays
  const rt = process.env.LAT_BOARD_RT;
  const cpus = process.env.LAT_BOARD_CPUS; // the board's port program on these CPUs (taskset)
  const argv = [...(cpus ? ['taskset', '-c', cpus] : []), ...(rt ? ['chrt', '-f', rt] : []), program, 'pty', link];
  const child = spawn(argv[0], argv.slice(1), { stdio: ['pipe', 'pipe', 'inherit'], env });
  let buf = Buffer.alloc(0);
  let opened;
  let readNs = null; // the time of the read that gave the next 'r' frame ('t' frame)
  const port = {
    slave: null,
    onData: null,
    opened: new Promise((resolve) => { opened = resolve; }),
    write(text) {
      const data = Buffer.from(text, 'latin1');
      const frame = Buffer.alloc(3 + data.length);
      frame.writeUInt16BE(1 + data.length, 0);
      frame[2] = 0x77; // 'w'
      data.copy(frame, 3);
      child.stdin.write(frame);
    },
    closed: false,
    close() { port.closed = true; child.stdin.end(); },
  };
  child.on('exit', (code, signal) => {
    if (!port.closed) { console.error(`port program exited (${code ?? signal})`); process.exit(1); }
  });
  child.stdout.on('data', (chunk) => {
    buf = buf.length ? Buffer.concat([buf, chunk]) : chunk;
    while (buf.length >= 2 && buf.length >= 2 + buf.readUInt16BE(0)) {
      const len = buf.readUInt16BE(0);
      const tag = String.fromCharCode(buf[2]);
      const data = buf.subarray(3, 2 + len);
      buf = buf.subarray(2 + len);
      if (tag === 't') readNs = BigInt(data.toString());
      else if (tag === 'r' && port.onData) { port.onData(data, readNs); readNs = null; }
      else if (tag === 'o') { port.slave = data.toString(); opened(); }
      else if (tag === 'e') { console.error(`port program: ${data.toString()}`); }
    }
  });
  return port;
}

// A raw Phoenix Channels v2 socket: push() resolves with the phx_reply payload.
function connect(name) {
  return channelsSocket(WebSocket, wsUrl(name));
}

// ---------------------------------------------------------------------------------------
// The observer process (LAT_ROLE=observers): its own OS process, commanded over IPC.

async function observers() {
  const sockets = [];
  let messages = 0;

  // an observer that has not joined (a ground station: heard nothing) within OBSERVER_OPEN_MS
  // counts as not joined, so the 'opened' answer always comes
  const openOne = (k) => Promise.race([GCS_PORT ? openGcs(k) : openWs(k), sleep(OBSERVER_OPEN_MS).then(() => false)]);
  // a ground station watching: its own socket (a session), a HEARTBEAT a second, frames
  // counted. Its close stops the heartbeat before the socket, and a send the socket can no
  // longer make is dropped, never thrown (a send on a closed UDP socket throws
  // ERR_SOCKET_DGRAM_NOT_RUNNING, which ended the process before it said 'closed').
  const openGcs = (k) => new Promise((resolve) => {
    const sock = dgram.createSocket('udp4');
    let open = true;
    let timer = null;
    const beat = () => {
      if (!open) return;
      try {
        sock.send(mavHeartbeat({ sysid: 200 + (k % 50) }), () => {}); // an error goes to the callback
      } catch {
        // closed under us
      }
    };
    sock.on('message', (buf) => { messages += frames(buf).length; });
    sock.on('error', () => resolve(false)); // e.g. ECONNREFUSED: nobody on the port
    sockets.push({
      close: () => {
        if (!open) return;
        open = false;
        clearInterval(timer);
        sock.close();
      },
    });
    sock.connect(GCS_PORT, '127.0.0.1', () => {
      if (!open) return;
      sock.once('message', () => resolve(true));
      beat();
      timer = setInterval(beat, 1000).unref();
    });
  });
  const openWs = (k) => new Promise((resolve) => {
    const ws = new WebSocket(wsUrl(`obs${k}`, OBSERVER_URL_BASE), { perMessageDeflate: false });
    const done = (ok) => { resolve(ok); };
    const telemetry = `[null,null,${JSON.stringify(TOPIC)},"telemetry"`;
    ws.on('message', (data) => {
      const text = data.toString();
      if (text.startsWith(telemetry)) messages++;
      else if (text.startsWith('["j","j"')) done(text.includes('"status":"ok"'));
    });
    ws.once('open', () => ws.send(JSON.stringify(['j', 'j', TOPIC, 'phx_join', {}])));
    ws.on('error', () => done(false)); // not once: a close while connecting is an error too
    sockets.push(ws);
    setInterval(() => { if (ws.readyState === 1) ws.send(JSON.stringify([null, 'hb', 'phoenix', 'heartbeat', {}])); }, 30000).unref();
  });

  const parentPort = { postMessage: (m) => process.send(m) };
  process.on('disconnect', () => process.exit(0)); // the pilot's process is gone
  process.on('message', async (m) => {
    if (m.type === 'open') {
      let next = 0, joined = 0;
      const total = m.count, base = sockets.length;
      await Promise.all(Array.from({ length: Math.min(WINDOW, total) }, async () => {
        while (next < total) { const k = base + next++; if (await openOne(k)) joined++; }
      }));
      parentPort.postMessage({ type: 'opened', joined: base + joined });
    } else if (m.type === 'count') {
      parentPort.postMessage({ type: 'counted', messages });
    } else if (m.type === 'close') {
      for (const ws of sockets) {
        try {
          ws.close(1000); // a ground station's close() takes no code
        } catch (err) {
          console.error(`observer process: a close failed: ${err.message}`);
        }
      }
      await sleep(500);
      parentPort.postMessage({ type: 'closed' });
      process.disconnect();
      process.exit(0);
    }
  });
}
