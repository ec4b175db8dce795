// Control latency of a mavlink vehicle: pilot command over the WebSocket → the MANUAL_CONTROL
// datagram that carries it, received by the vehicle. Prints figures, asserts nothing. Started by
// bench/control_latency_mavlink, which starts the server once this process listens:
//
//   LAT_URL=ws://127.0.0.1:4214 LAT_MAV_PORT=14650 node bench/control_latency_mavlink.mjs [SAMPLES]
//
// This process is the pilot and the vehicle. The vehicle is a minimal ArduSub stand-in on UDP
// (LAT_MAV_PORT on 127.0.0.1; the server's board sends to it, `mavlink:udpout:…`): HEARTBEAT at
// 1 Hz as a submarine (system 1) so the board's link is up, and every MANUAL_CONTROL datagram
// timed on arrival (process.hrtime, the clock the pilot's sends are timed on). The pilot joins
// `vehicle:LAT_VEHICLE`, takes the helm, heartbeats every 100 ms and sends SAMPLES motion
// thrust commands (surge 0.02..0.80 so consecutive commands differ, 5–15 ms apart, one at a
// time): each is timed from the send to the first MANUAL_CONTROL with its `x` (gain 0.5:
// x = 500 · surge). Then SAMPLES / 10 stops (`stop` after a non-neutral command): send →
// the neutral MANUAL_CONTROL. And the MANUAL_CONTROL period while nothing changes.
//
// Environment: LAT_URL (ws://127.0.0.1:4214), LAT_MAV_PORT (14650), LAT_VEHICLE (sub),
// LAT_READY_FILE (written once the vehicle listens).

import { createRequire } from 'node:module';
import dgram from 'node:dgram';
import { writeFileSync } from 'node:fs';
import { channelsSocket } from './support/channels.mjs';

const require = createRequire(new URL('../assets/package.json', import.meta.url));
const WebSocket = require('ws');

const URL_BASE = process.env.LAT_URL ?? 'ws://127.0.0.1:4214';
const PORT = Number(process.env.LAT_MAV_PORT ?? 14650);
const VEHICLE = process.env.LAT_VEHICLE ?? 'sub';
const TOPIC = `vehicle:${VEHICLE}`;
const SAMPLES = Number(process.argv[2] ?? process.env.LAT_SAMPLES ?? 1000);
const out = (label, value) => console.log(`${(label + ':').padEnd(46)} ${value}`);
const now = () => Number(process.hrtime.bigint()) / 1e6;

// --- MAVLink, the little the vehicle needs -------------------------------------------------

function x25(bytes, crc = 0xffff) {
  for (const b of bytes) {
    let tmp = b ^ (crc & 0xff);
    tmp = (tmp ^ (tmp << 4)) & 0xff;
    crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xffff;
  }
  return crc;
}

let seq = 0;
function heartbeat(armed) {
  // HEARTBEAT (0, CRC_EXTRA 50): custom_mode u32 19 (MANUAL), type 12, autopilot 3, base_mode, status 4, version 3
  const payload = Buffer.from([19, 0, 0, 0, 12, 3, armed ? 209 : 81, 4, 3]);
  const head = Buffer.from([0xfd, payload.length, 0, 0, seq, 1, 1, 0, 0, 0]);
  seq = (seq + 1) % 256;
  const body = Buffer.concat([head.subarray(1), payload]);
  const crc = x25([50], x25(body));
  return Buffer.concat([head, payload, Buffer.from([crc & 0xff, crc >> 8])]);
}

// MANUAL_CONTROL (69): x y z r int16, buttons u16, target u8 (zero-extended: MAVLink 2 truncates)
function manualControl(msg) {
  if (msg[0] !== 0xfd) return null;
  const len = msg[1];
  const id = msg[7] | (msg[8] << 8) | (msg[9] << 16);
  if (id !== 69) return null;
  const p = Buffer.alloc(11);
  msg.copy(p, 0, 10, 10 + Math.min(len, 11));
  return { x: p.readInt16LE(0), z: p.readInt16LE(4), r: p.readInt16LE(6) };
}

// --- the vehicle ----------------------------------------------------------------------------

const sock = dgram.createSocket('udp4');
let peer = null;
let waiter = null; // { pred, resolve }
const arrivals = [];
sock.on('message', (msg, rinfo) => {
  const at = now();
  peer = rinfo;
  const mc = manualControl(msg);
  if (!mc) return;
  arrivals.push(at);
  if (arrivals.length > 1000) arrivals.shift();
  if (waiter && waiter.pred(mc)) { const w = waiter; waiter = null; w.resolve(at); }
});
await new Promise((res) => sock.bind(PORT, '127.0.0.1', res));
setInterval(() => { if (peer) sock.send(heartbeat(true), peer.port, peer.address); }, 1000);
if (process.env.LAT_READY_FILE) writeFileSync(process.env.LAT_READY_FILE, String(PORT));

const datagram = (pred, ms = 2000) => new Promise((resolve, reject) => {
  const timer = setTimeout(() => { waiter = null; reject(new Error('no such MANUAL_CONTROL')); }, ms);
  waiter = { pred, resolve: (at) => { clearTimeout(timer); resolve(at); } };
});

// --- the pilot ------------------------------------------------------------------------------

async function connect() {
  for (let i = 0; i < 600; i++) {
    try { return await channelsSocket(WebSocket, `${URL_BASE}/socket/websocket?vsn=2.0.0&name=bench-pilot`); }
    catch { await new Promise((r) => setTimeout(r, 100)); }
  }
  throw new Error(`no server at ${URL_BASE}`);
}

const pilot = await connect();
await pilot.push(TOPIC, 'phx_join', {});
// the board's link up: the vehicle's heartbeat reached it (the first one goes once it sent us its own)
for (let i = 0; i < 100 && !peer; i++) await new Promise((r) => setTimeout(r, 100));
await new Promise((r) => setTimeout(r, 1500));
const grant = await pilot.push(TOPIC, 'request_control', {});
const epoch = grant.response?.grant?.epoch;
if (grant.status !== 'ok') throw new Error(`request_control: ${JSON.stringify(grant)}`);
setInterval(() => pilot.push(TOPIC, 'heartbeat', {}), 100);

const pct = (xs, p) => { const s = [...xs].sort((a, b) => a - b); return s[Math.min(s.length - 1, Math.floor((p / 100) * s.length))]; };
const figures = (xs) => `p50 ${pct(xs, 50).toFixed(2)} / p90 ${pct(xs, 90).toFixed(2)} / p99 ${pct(xs, 99).toFixed(2)} / max ${Math.max(...xs).toFixed(2)} ms`;

const latencies = [], replies = [];
let lost = 0;
for (let i = 0; i < SAMPLES; i++) {
  const surge = 0.02 + (i % 40) * 0.02; // 0.02..0.80, consecutive ones differ
  const x = Math.round(500 * surge);
  const arrived = datagram((mc) => mc.x === x);
  const sent = now();
  const reply = pilot.push(TOPIC, 'thrust', { mode: 'motion', surge, heave: 0, yaw: 0, epoch });
  try { latencies.push((await arrived) - sent); } catch { lost++; }
  await reply;
  replies.push(now() - sent);
  await new Promise((r) => setTimeout(r, 5 + Math.random() * 10));
}

const stops = [];
for (let i = 0; i < Math.max(10, SAMPLES / 10); i++) {
  await pilot.push(TOPIC, 'thrust', { mode: 'motion', surge: 0.5, heave: 0, yaw: 0, epoch });
  await new Promise((r) => setTimeout(r, 20));
  const neutral = datagram((mc) => mc.x === 0 && mc.z === 500 && mc.r === 0);
  const sent = now();
  await pilot.push(TOPIC, 'stop', {});
  try { stops.push((await neutral) - sent); } catch { lost++; }
  await new Promise((r) => setTimeout(r, 20));
}

arrivals.length = 0;
await new Promise((r) => setTimeout(r, 3000));
const periods = arrivals.slice(1).map((t, i) => t - arrivals[i]);

out('samples (thrust, stop)', `${latencies.length}, ${stops.length} (${lost} without a matching datagram)`);
out('thrust → MANUAL_CONTROL received', figures(latencies));
out('thrust → phx_reply', figures(replies));
out('stop → neutral MANUAL_CONTROL received', figures(stops));
out('MANUAL_CONTROL period while unchanged', `${figures(periods)} (${periods.length} periods)`);
process.exit(0);
