// Flies the fake server (fake_server.mjs) through the commands it implements, with two raw
// Phoenix Channels v2 clients, and prints every frame they received as JSON:
// `[{"pushed": EVENT | null, "frame": [join_ref, ref, topic, event, payload]}]` (`pushed`: the
// event the frame replies to). test/neptunus_web/wire_schema_test.exs checks them against the
// wire schema.
//
//   node test/support/fake_server_sample.mjs

import WebSocket from "ws";
import { startFakeServer } from "./fake_server.mjs";

const VEHICLE = "vehicle:neptunus-1";
const server = await startFakeServer(0);
const received = [];
let nextRef = 1;

function client(name) {
  const ws = new WebSocket(`${server.url.replace(/^http/, "ws")}/socket/websocket?vsn=2.0.0&name=${name}`);
  const pushed = new Map(); // ref -> event
  const waiting = []; // {match, resolve}
  const inbox = []; // frames no one waited for yet
  const joins = new Map(); // topic -> join_ref
  ws.on("message", (data) => {
    const frame = JSON.parse(String(data));
    const ref = frame[1];
    received.push({ pushed: frame[3] === "phx_reply" ? (pushed.get(ref) ?? null) : null, frame });
    const i = waiting.findIndex((w) => w.match(frame));
    if (i >= 0) waiting.splice(i, 1)[0].resolve(frame);
    else inbox.push(frame);
  });
  const opened = new Promise((resolve) => ws.on("open", resolve));
  const next = (match) =>
    new Promise((resolve, reject) => {
      const i = inbox.findIndex(match);
      if (i >= 0) return resolve(inbox.splice(i, 1)[0]);
      const timer = setTimeout(() => reject(new Error(`${name}: timed out`)), 3000);
      waiting.push({ match, resolve: (f) => (clearTimeout(timer), resolve(f)) });
    });
  const push = async (topic, event, payload = {}) => {
    await opened;
    const ref = String(nextRef++);
    if (event === "phx_join") joins.set(topic, ref);
    pushed.set(ref, event);
    const reply = next((f) => f[1] === ref && f[3] === "phx_reply");
    ws.send(JSON.stringify([joins.get(topic) ?? null, ref, topic, event, payload]));
    const frame = await reply;
    return frame[4].response;
  };
  const event = (name_, pred = () => true) => next((f) => f[3] === name_ && pred(f[4]));
  return { push, event, close: () => ws.close() };
}

const ada = client("ada");
const bob = client("bob");
await ada.push("fleet", "phx_join");
await ada.push("log:neptunus-1", "phx_join");
await ada.push(VEHICLE, "phx_join");
const telemetry = ada.event("telemetry");
await bob.push(VEHICLE, "phx_join");
await telemetry;

const { grant } = await ada.push(VEHICLE, "request_control");
await ada.push(VEHICLE, "heartbeat");
await ada.push(VEHICLE, "thrust", { mode: "motion", surge: 0.5, heave: 0, yaw: 0.1, epoch: grant.epoch });
await ada.push(VEHICLE, "set_gain", { value: 0.7 });
await ada.push(VEHICLE, "stop", { reason: "sample" });
await bob.push(VEHICLE, "request_control");
await ada.push(VEHICLE, "answer_request", { accept: false });
await bob.event("request_denied");
await bob.push(VEHICLE, "request_control");
await ada.push(VEHICLE, "answer_request", { accept: true });
await bob.event("control_granted");
await bob.push(VEHICLE, "release_control");
await ada.event("helm", (h) => h.state === "free");

ada.close();
bob.close();
await server.close();
process.stdout.write(JSON.stringify(received));
