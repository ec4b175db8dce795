// One observer on a slow link (see bench/slow_link): joins the vehicle's topic, reads every
// frame as the link delivers it, and reports how old the telemetry is when it arrives
// (receive time − payload.sent_at; server and observer share the machine's clock).
//
//   node bench/slow_link.mjs URL TOPIC SECONDS
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';
import path from 'node:path';

const here = path.dirname(fileURLToPath(import.meta.url));
const require = createRequire(path.join(here, '../assets/package.json'));
const WebSocket = require('ws');

const [url, topic, secondsArg] = process.argv.slice(2);
const seconds = Number(secondsArg);
if (!url || !topic || !(seconds > 0)) {
  console.error('usage: node bench/slow_link.mjs URL TOPIC SECONDS');
  process.exit(2);
}

const TELEMETRY = `[null,null,${JSON.stringify(topic)},"telemetry",`;
const all = [];
let window = [];
let bytes = 0;
let joined = false;
const started = Date.now();

const pct = (sorted, p) => sorted[Math.min(sorted.length - 1, Math.max(0, Math.ceil((p / 100) * sorted.length) - 1))];
const summary = (ages) => {
  if (!ages.length) return 'no telemetry';
  const s = [...ages].sort((a, b) => a - b);
  return `${String(s.length).padStart(4)} frames (${(s.length / 10).toFixed(1)}/s), age p50 ${pct(s, 50).toFixed(0)} / max ${s[s.length - 1].toFixed(0)} ms`;
};

const ws = new WebSocket(url, { perMessageDeflate: false });
ws.on('error', (e) => { console.error(`slow_link: ${e.message}`); process.exit(1); });
ws.on('open', () => {
  ws.send(JSON.stringify(['1', '1', topic, 'phx_join', {}]));
  setInterval(() => ws.send(JSON.stringify([null, 'hb', 'phoenix', 'heartbeat', {}])), 20_000).unref();
});
ws.on('close', (code) => { if (Date.now() - started < seconds * 1000) { console.error(`slow_link: closed by the server (${code})`); process.exit(1); } });
ws.on('message', (data) => {
  bytes += data.length;
  const text = data.toString();
  if (text.startsWith('["1","1"')) {
    joined = text.includes('"status":"ok"');
    if (!joined) { console.error(`slow_link: join refused: ${text.slice(0, 200)}`); process.exit(1); }
  } else if (text.startsWith(TELEMETRY)) {
    const m = text.match(/"sent_at":([0-9.]+)/);
    if (m) { const age = Date.now() - Number(m[1]); all.push(age); window.push(age); }
  }
});

console.log('every 10 s: telemetry frames received and their age on arrival');
const tick = setInterval(() => {
  console.log(`  ${String(Math.round((Date.now() - started) / 1000)).padStart(4)} s: ${summary(window)}`);
  window = [];
}, 10_000);

setTimeout(() => {
  clearInterval(tick);
  const s = [...all].sort((a, b) => a - b);
  const last = s.length ? all.slice(-Math.max(1, Math.floor(all.length / 4))).sort((a, b) => a - b) : [];
  const out = (k, v) => console.log(`${k.padEnd(45)}${v}`);
  out('telemetry frames received', `${all.length} (${(all.length / seconds).toFixed(1)}/s of 20/s sent)`);
  out('bytes received', `${(bytes / seconds / 1024).toFixed(1)} KiB/s`);
  if (s.length) {
    out('age on arrival p50 / p99 / max', `${pct(s, 50).toFixed(0)} / ${pct(s, 99).toFixed(0)} / ${s[s.length - 1].toFixed(0)} ms`);
    out('the same, last quarter of the run (settled)', `${pct(last, 50).toFixed(0)} / ${pct(last, 99).toFixed(0)} / ${last[last.length - 1].toFixed(0)} ms`);
  }
  ws.terminate();
  process.exit(0);
}, seconds * 1000);
