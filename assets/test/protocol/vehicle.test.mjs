// Protocol test: the official `phoenix` JS client (with `ws` as its transport) against a running
// Neptunus server, exactly as the browser talks to it.
//
//   NEPTUNUS_URL=http://127.0.0.1:4102 node --test test/protocol/      (from assets/)
//
// NEPTUNUS_URL defaults to http://127.0.0.1:4000; NEPTUNUS_VEHICLE to neptunus-1.
// Drives the vehicle: run it against a simulated board only. Every wait has a timeout and all
// sockets are closed at the end, so the process exits whether the server is there or not.

import assert from "node:assert/strict";
import { after, before, test } from "node:test";
import { Socket } from "phoenix";
import WebSocket from "ws";

const BASE = (process.env.NEPTUNUS_URL || "http://127.0.0.1:4000").replace(/\/+$/, "");
const SOCKET_URL = `${BASE.replace(/^http/, "ws")}/socket`;
const VEHICLE = process.env.NEPTUNUS_VEHICLE || "neptunus-1";
const TOPIC = `vehicle:${VEHICLE}`;
const NAME = "node-test";
const OTHER_NAME = "node-test-observer";

// Bounds of waits for what must come (a reply, an event, telemetry): generous, since the
// machine may be busy; every wait ends as soon as it comes. Nothing here measures speed.
const REPLY_MS = 15000;
const TEST_MS = 60000;

// ---------------------------------------------------------------------------------------------
// Helpers

/** Every `ws` connection the phoenix clients open, so none can outlive the test. */
const transports = new Set();
class TrackedWebSocket extends WebSocket {
  constructor(...args) {
    super(...args);
    transports.add(this);
    this.on("close", () => transports.delete(this));
  }
}

function timeout(ms, what) {
  let timer;
  const promise = new Promise((_, reject) => {
    timer = setTimeout(() => reject(new Error(`timed out after ${ms} ms waiting for ${what}`)), ms);
  });
  return { promise, cancel: () => clearTimeout(timer) };
}

async function within(ms, what, promise) {
  const t = timeout(ms, what);
  try {
    return await Promise.race([promise, t.promise]);
  } finally {
    t.cancel();
  }
}

/** Resolves with {status: "ok"|"error", response}; rejects on the client's push timeout. */
function reply(push, what) {
  return new Promise((resolve, reject) => {
    push
      .receive("ok", (response) => resolve({ status: "ok", response }))
      .receive("error", (response) => resolve({ status: "error", response }))
      .receive("timeout", () => reject(new Error(`no reply to ${what} within ${REPLY_MS} ms`)));
  });
}

function openSocket(name) {
  const socket = new Socket(SOCKET_URL, {
    transport: TrackedWebSocket,
    params: { name },
    reconnectAfterMs: () => 500,
    rejoinAfterMs: () => 500,
  });
  const opened = new Promise((resolve, reject) => {
    socket.onOpen(() => resolve());
    socket.onError((err) =>
      reject(new Error(`WebSocket ${SOCKET_URL}/websocket failed: ${errText(err)}`)),
    );
  });
  socket.connect();
  return { socket, opened: within(REPLY_MS, `WebSocket ${SOCKET_URL}/websocket`, opened) };
}

function errText(err) {
  if (err && typeof err === "object" && "message" in err && err.message) return err.message;
  if (err && typeof err === "object" && "type" in err) return String(err.type);
  return String(err);
}

/**
 * Heartbeats on `side`'s channel every `ms`, as the operator page does while it pilots (the
 * helm stops a pilot silent for its deadman, 500 ms): the tests' pilots must not be stopped
 * by a busy machine's pause between two of their steps. Refused while `side` does not pilot.
 */
function keepAlive(side, ms) {
  clearInterval(side.heartbeat);
  side.heartbeat = setInterval(() => {
    if (side.channel?.state === "joined") side.channel.push("heartbeat", {}, REPLY_MS);
  }, ms);
}

async function closeSocket(socket) {
  if (!socket) return;
  await within(2000, "socket close", new Promise((resolve) => socket.disconnect(resolve))).catch(
    () => undefined,
  );
}

/** Collects a channel's events; `next(event, pred, ms)` waits for a matching one. */
function recorder(channel, events) {
  const seen = Object.fromEntries(events.map((e) => [e, []]));
  const waiters = new Set();
  for (const event of events) {
    channel.on(event, (payload) => {
      seen[event].push(payload);
      for (const w of [...waiters]) {
        if (w.event === event && w.pred(payload)) {
          waiters.delete(w);
          w.resolve(payload);
        }
      }
    });
  }
  return {
    seen,
    last: (event) => seen[event].at(-1),
    /** The next `event` (from now on) for which `pred` holds. */
    next(event, pred, ms, what) {
      let waiter;
      const p = new Promise((resolve) => {
        waiter = { event, pred, resolve };
        waiters.add(waiter);
      });
      return within(ms, what, p).finally(() => waiters.delete(waiter));
    },
    /** A matching `event` already seen, else the next one. */
    seenOrNext(event, pred, ms, what) {
      const found = seen[event].find(pred);
      return found !== undefined ? Promise.resolve(found) : this.next(event, pred, ms, what);
    },
  };
}

const isNum = (v) => typeof v === "number" && Number.isFinite(v);

function assertNumbers(obj, keys, where) {
  assert.ok(obj && typeof obj === "object", `${where} must be an object, got ${JSON.stringify(obj)}`);
  for (const k of keys) assert.ok(isNum(obj[k]), `${where}.${k} must be a finite number, got ${JSON.stringify(obj[k])}`);
}

/** Outputs in [-1, 1]; the pulse widths (1000..2000 µs) are required in telemetry only. */
function assertThrusters(th, where, { pulseWidths = true } = {}) {
  assertNumbers(th, ["port", "vertical", "starboard"], where);
  if (pulseWidths) assertNumbers(th, ["port_us", "vertical_us", "starboard_us"], where);
  for (const k of ["port", "vertical", "starboard"]) {
    assert.ok(th[k] >= -1 && th[k] <= 1, `${where}.${k} = ${th[k]} outside [-1, 1]`);
    const us = th[`${k}_us`];
    if (us !== undefined) assert.ok(us >= 1000 && us <= 2000, `${where}.${k}_us = ${us} outside 1000..2000`);
  }
}

function assertTelemetry(t, where = "telemetry") {
  assert.ok(t && typeof t === "object", `${where} must be an object`);
  assert.ok(isNum(t.t), `${where}.t must be a number`);
  assert.ok(isNum(t.sent_at), `${where}.sent_at must be a number (epoch ms)`);
  assert.ok(
    Math.abs(t.sent_at - Date.now()) < 60_000,
    `${where}.sent_at = ${t.sent_at} is not epoch milliseconds near now (${Date.now()})`,
  );
  // each measurement: a number once valid (or stale), null while it is initialising (docs/API.md)
  const states = t.measurement_state;
  assert.ok(states && typeof states === "object", `${where}.measurement_state must be an object`);
  for (const k of ["depth", "heading", "roll", "pitch", "voltage", "current"]) {
    const state = states[k];
    assert.ok(["initialising", "valid", "stale"].includes(state), `${where}.measurement_state.${k} = ${JSON.stringify(state)}`);
    if (state === "initialising") assert.equal(t.measurement[k], null, `${where}.measurement.${k} must be null while initialising`);
    else assertNumbers(t.measurement, [k], `${where}.measurement`);
  }
  if (states.heading !== "initialising") {
    assert.ok(
      t.measurement.heading >= 0 && t.measurement.heading < 2 * Math.PI,
      `${where}.measurement.heading = ${t.measurement.heading} rad outside [0, 2π)`,
    );
  }
  assertNumbers(t.sim, ["x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r"], `${where}.sim`);
  assertNumbers(t.command, ["surge", "heave", "yaw"], `${where}.command`);
  assertThrusters(t.thrusters, `${where}.thrusters`);
}

const thrustersAtZero = (t) =>
  Math.abs(t.thrusters.port) < 1e-9 &&
  Math.abs(t.thrusters.vertical) < 1e-9 &&
  Math.abs(t.thrusters.starboard) < 1e-9;

const commandAtZero = (t) => t.command.surge === 0 && t.command.heave === 0 && t.command.yaw === 0;

const VEHICLE_EVENTS = [
  "telemetry",
  "presence_state",
  "presence_diff",
  "helm",
  "stopped",
  "control_request",
  "control_granted",
  "control_lost",
  "request_denied",
];

const motion = (surge, epoch) => ({ mode: "motion", surge, heave: 0, yaw: 0, epoch });

function assertHelm(h, where = "helm") {
  assert.ok(h && typeof h === "object", `${where} must be an object`);
  assert.ok(["free", "piloted", "requested", "takeover"].includes(h.state), `${where}.state = ${JSON.stringify(h.state)}`);
  assertNumbers(h, ["epoch", "deadman_ms", "heartbeat_ms", "request_timeout_ms", "takeover_ms"], where);
  if (h.state === "free") assert.equal(h.pilot, null, `${where}.pilot must be null when free`);
  else assert.equal(typeof h.pilot?.name, "string", `${where}.pilot must name the pilot`);
}

// ---------------------------------------------------------------------------------------------
// Fixture: one pilot socket for the whole file, a second client for the helm tests.
// Helm (docs/API.md): request_control on a free helm grants at once; thrust must carry the
// grant's `epoch`; control passes by request and acknowledge.

let pilot; // {socket, channel, events, epoch}
let observer;
let snapshot;

before(async () => {
  try {
    const res = await fetch(`${BASE}/api/health`, { signal: AbortSignal.timeout(REPLY_MS) });
    assert.equal(res.status, 200, `GET ${BASE}/api/health answered ${res.status}`);
  } catch (err) {
    throw new Error(
      `Neptunus server not reachable at ${BASE} (${errText(err.cause ?? err)}). ` +
        "Start it (e.g. `NEPTUNUS_PORT=4102 mix run --no-halt`) and set NEPTUNUS_URL.",
    );
  }
  const { socket, opened } = openSocket(NAME);
  pilot = { socket };
  await opened;
});

after(async () => {
  clearInterval(pilot?.heartbeat);
  clearInterval(observer?.heartbeat);
  // Leave the vehicle stopped, whatever happened above.
  for (const side of [pilot, observer]) {
    if (side?.channel?.state === "joined") {
      await within(REPLY_MS, "final release", reply(side.channel.push("release_control", {}, REPLY_MS), "release")).catch(() => undefined);
    }
  }
  await closeSocket(pilot?.socket);
  await closeSocket(observer?.socket);
  for (const ws of transports) ws.terminate();
});

// ---------------------------------------------------------------------------------------------

test("fleet: join reply lists the vehicles", { timeout: TEST_MS }, async () => {
  const channel = pilot.socket.channel("fleet", {});
  const { status, response } = await reply(channel.join(REPLY_MS), "join fleet");
  assert.equal(status, "ok", `join fleet refused: ${JSON.stringify(response)}`);
  assert.ok(Array.isArray(response.vehicles), `fleet reply must have vehicles[]: ${JSON.stringify(response)}`);
  for (const v of response.vehicles) {
    assert.equal(typeof v.id, "string");
    assert.equal(typeof v.board, "string");
  }
  assert.ok(
    response.vehicles.some((v) => v.id === VEHICLE),
    `fleet does not list ${VEHICLE}: ${JSON.stringify(response.vehicles)}`,
  );
  await reply(channel.leave(REPLY_MS), "leave fleet").catch(() => undefined);
});

test(`${TOPIC}: join reply is a snapshot`, { timeout: TEST_MS }, async () => {
  const channel = pilot.socket.channel(TOPIC, {});
  // register before joining: presence_state and telemetry follow the reply immediately
  const events = recorder(channel, VEHICLE_EVENTS);
  pilot.channel = channel;
  pilot.events = events;
  const { status, response } = await reply(channel.join(REPLY_MS), `join ${TOPIC}`);
  assert.equal(status, "ok", `join ${TOPIC} refused: ${JSON.stringify(response)}`);
  snapshot = response;
  for (const key of ["vehicle", "telemetry", "pilot", "helm", "control", "session"]) {
    assert.ok(key in response, `snapshot has no "${key}": ${JSON.stringify(response)}`);
  }
  assert.equal(response.vehicle.id, VEHICLE);
  assert.equal(typeof response.vehicle.board, "string");
  if (response.telemetry !== null) assertTelemetry(response.telemetry, "snapshot.telemetry");
  assertHelm(response.helm, "snapshot.helm");
  assert.equal(response.session.name, NAME, `session names us: ${JSON.stringify(response.session)}`);
  assert.equal(response.session.mode, "local", "the test server runs in local mode");
  assert.equal(typeof response.session.id, "string");
});

test("presence_state lists this client", { timeout: TEST_MS }, async () => {
  const state = await pilot.events.seenOrNext("presence_state", () => true, REPLY_MS, "presence_state");
  assert.ok(state && typeof state === "object" && !Array.isArray(state), "presence_state must be an object");
  for (const [key, value] of Object.entries(state)) {
    assert.ok(Array.isArray(value?.metas) && value.metas.length > 0, `presence ${key} must have metas[]`);
    for (const meta of value.metas) assert.equal(typeof meta.phx_ref, "string", `presence ${key} meta needs phx_ref`);
  }
  const mine = Object.entries(state).filter(
    ([key, value]) => key === NAME || value.metas.some((m) => m.name === NAME),
  );
  assert.ok(mine.length > 0, `presence_state has no entry named ${NAME}: ${JSON.stringify(state)}`);
});

test("telemetry arrives with the documented shape", { timeout: TEST_MS }, async () => {
  const first = await pilot.events.seenOrNext("telemetry", () => true, REPLY_MS, "telemetry");
  assertTelemetry(first);
  // 20 Hz nominal: 5 samples, with vehicle time moving forward
  const start = pilot.events.seen.telemetry.length;
  await pilot.events.next("telemetry", () => pilot.events.seen.telemetry.length >= start + 5, REPLY_MS, "5 telemetry samples");
  const recent = pilot.events.seen.telemetry.slice(start);
  recent.forEach((t, i) => assertTelemetry(t, `telemetry[${i}]`));
  for (let i = 1; i < recent.length; i++) {
    assert.ok(recent[i].t > recent[i - 1].t, `telemetry t must increase: ${recent[i - 1].t} then ${recent[i].t}`);
  }
});

test("request_control on a free helm grants at once; thrust with the grant's epoch moves the vehicle", { timeout: TEST_MS }, async () => {
  const { channel, events } = pilot;
  const before = events.last("telemetry");
  assert.ok(before, "no telemetry yet");
  if (snapshot.helm.state !== "free") {
    assert.fail(`another client pilots ${VEHICLE} (helm: ${JSON.stringify(snapshot.helm)}); close it and rerun`);
  }

  // before the grant: refused, nothing moves
  const early = await reply(channel.push("thrust", motion(1, snapshot.helm.epoch), REPLY_MS), "thrust before grant");
  assert.equal(early.status, "error");
  assert.equal(early.response.reason, "not_in_control");

  const granted = await reply(channel.push("request_control", {}, REPLY_MS), "request_control");
  assert.equal(granted.status, "ok", `request_control refused: ${JSON.stringify(granted.response)}`);
  assert.equal(granted.response.status, "granted");
  const grant = granted.response.grant;
  assertNumbers(grant, ["epoch", "deadman_ms", "heartbeat_ms"], "grant");
  assert.equal(grant.pilot.id, snapshot.session.id, "the grant names this connection");
  assert.equal(grant.control.mode, "motion");
  assertNumbers(grant.control.command, ["surge", "heave", "yaw"], "grant.control.command");
  pilot.epoch = grant.epoch;
  keepAlive(pilot, grant.heartbeat_ms);
  await events.seenOrNext("control_granted", (g) => g.epoch === grant.epoch, REPLY_MS, "control_granted");
  await events.seenOrNext("helm", (h) => h.state === "piloted" && h.pilot?.name === NAME, REPLY_MS, "helm naming us");

  const stale = await reply(channel.push("thrust", motion(1, grant.epoch - 1), REPLY_MS), "stale thrust");
  assert.equal(stale.status, "error");
  assert.equal(stale.response.reason, "stale_command", "a command stamped before the grant must be refused");

  const { status, response } = await reply(channel.push("thrust", motion(1, grant.epoch), REPLY_MS), "thrust");
  assert.equal(status, "ok", `thrust refused: ${JSON.stringify(response)}`);
  assertNumbers(response.command, ["surge", "heave", "yaw"], "reply.command");
  assert.ok(response.command.surge > 0, `reply.command.surge = ${response.command.surge}, expected > 0`);
  assertThrusters(response.thrusters, "reply.thrusters", { pulseWidths: false });
  assert.ok(
    Math.abs(response.thrusters.port) > 0 && Math.abs(response.thrusters.starboard) > 0,
    `surge must drive port and starboard: ${JSON.stringify(response.thrusters)}`,
  );

  const hb = await reply(channel.push("heartbeat", {}, REPLY_MS), "heartbeat");
  assert.equal(hb.status, "ok", `the pilot's heartbeat refused: ${JSON.stringify(hb.response)}`);

  const moved = await events.next(
    "telemetry",
    (t) => t.sim.u > before.sim.u + 0.01 || t.sim.x > before.sim.x + 0.01,
    REPLY_MS,
    `sim.u or sim.x to increase from u=${before.sim.u}, x=${before.sim.x}`,
  );
  assertTelemetry(moved);
  assert.ok(moved.command.surge > 0, "telemetry command.surge should show the thrust");
});

test("another client is refused with not_in_control and changes nothing", { timeout: TEST_MS }, async () => {
  const { socket, opened } = openSocket(OTHER_NAME);
  observer = { socket };
  await opened;
  const channel = socket.channel(TOPIC, {});
  const events = recorder(channel, VEHICLE_EVENTS);
  observer.channel = channel;
  observer.events = events;
  const join = await reply(channel.join(REPLY_MS), `observer join ${TOPIC}`);
  assert.equal(join.status, "ok");
  observer.session = join.response.session;
  keepAlive(observer, join.response.helm.heartbeat_ms);
  assert.equal(join.response.helm.pilot?.name, NAME, `the snapshot's helm should name the pilot: ${JSON.stringify(join.response.helm)}`);

  // the pilot sees the observer arrive
  await pilot.events.seenOrNext(
    "presence_diff",
    (d) => Object.entries(d?.joins ?? {}).some(([k, v]) => k === OTHER_NAME || v.metas?.some((m) => m.name === OTHER_NAME)),
    REPLY_MS,
    `presence_diff joining ${OTHER_NAME}`,
  );

  for (const [event, payload] of [
    ["thrust", motion(-1, pilot.epoch)],
    ["stop", { reason: "observer" }],
    ["heartbeat", {}],
    ["answer_request", { accept: true }],
    ["release_control", {}],
  ]) {
    const { status, response } = await reply(channel.push(event, payload, REPLY_MS), `observer ${event}`);
    assert.equal(status, "error", `observer's ${event} was accepted: ${JSON.stringify(response)}`);
    assert.equal(response.reason, "not_in_control", `observer's ${event}`);
  }
  // and nothing changed: the pilot's surge is still commanded
  const t = await events.next("telemetry", () => true, REPLY_MS, "observer telemetry");
  assert.ok(t.command.surge > 0, `observer's refused command changed the vehicle: ${JSON.stringify(t.command)}`);
});

test("control passes by request and acknowledge, neutral on transfer", { timeout: TEST_MS }, async () => {
  const pending = await reply(observer.channel.push("request_control", {}, REPLY_MS), "observer request_control");
  assert.equal(pending.status, "ok", JSON.stringify(pending.response));
  assert.equal(pending.response.status, "pending");
  const request = await pilot.events.seenOrNext("control_request", () => true, REPLY_MS, "control_request to the pilot");
  assert.equal(request.from.name, OTHER_NAME);

  const answer = await reply(pilot.channel.push("answer_request", { accept: true }, REPLY_MS), "answer_request");
  assert.equal(answer.status, "ok", JSON.stringify(answer.response));
  const grant = await observer.events.seenOrNext("control_granted", () => true, REPLY_MS, "control_granted");
  assert.ok(grant.epoch > pilot.epoch, "a transfer starts a new epoch");
  await pilot.events.seenOrNext("control_lost", (l) => l.reason === "control_transferred", REPLY_MS, "control_lost");
  await observer.events.seenOrNext("stopped", (s) => s.reason === "control_transferred", REPLY_MS, "stopped on transfer");
  await observer.events.next("telemetry", (t) => commandAtZero(t), REPLY_MS, "neutral after the transfer");

  const old = await reply(pilot.channel.push("thrust", motion(1, pilot.epoch), REPLY_MS), "old pilot's thrust");
  assert.equal(old.response.reason, "not_in_control");
  const stale = await reply(observer.channel.push("thrust", motion(1, pilot.epoch), REPLY_MS), "pre-grant stamp");
  assert.equal(stale.response.reason, "stale_command");

  // and back (denied once first)
  const again = await reply(pilot.channel.push("request_control", {}, REPLY_MS), "pilot requests back");
  assert.equal(again.response.status, "pending");
  await observer.events.seenOrNext("control_request", (r) => r.from.name === NAME, REPLY_MS, "request from the pilot");
  await reply(observer.channel.push("answer_request", { accept: false }, REPLY_MS), "deny");
  const denied = await pilot.events.seenOrNext("request_denied", () => true, REPLY_MS, "request_denied");
  assert.equal(denied.reason, "denied");

  // listen first: the request reaches the observer's connection before the reply reaches ours
  const second = observer.events.next("control_request", (r) => r.from.name === NAME, REPLY_MS, "second request");
  await reply(pilot.channel.push("request_control", {}, REPLY_MS), "pilot requests again");
  await second;
  // listen first here too: the grant may reach the pilot before the accept reply reaches us
  const granted = pilot.events.next("control_granted", () => true, REPLY_MS, "control back");
  await reply(observer.channel.push("answer_request", { accept: true }, REPLY_MS), "accept");
  const back = await granted;
  pilot.epoch = back.epoch;
});

test("stop puts every thruster at zero", { timeout: TEST_MS }, async () => {
  const { channel, events } = pilot;
  const go = await reply(channel.push("thrust", motion(0.5, pilot.epoch), REPLY_MS), "thrust");
  assert.equal(go.status, "ok", `thrust refused: ${JSON.stringify(go.response)}`);
  const { status, response } = await reply(channel.push("stop", { reason: "protocol test" }, REPLY_MS), "stop");
  assert.equal(status, "ok", `stop refused: ${JSON.stringify(response)}`);
  await observer.events.seenOrNext("stopped", (s) => s.reason === "protocol test", REPLY_MS, "stopped with our reason");
  const t = await events.next(
    "telemetry",
    (x) => thrustersAtZero(x) && commandAtZero(x),
    REPLY_MS,
    "telemetry with thrusters and command at zero",
  );
  for (const k of ["port_us", "vertical_us", "starboard_us"]) {
    assert.ok(Math.abs(t.thrusters[k] - 1500) <= 1, `${k} = ${t.thrusters[k]} after stop, expected 1500 (neutral)`);
  }
});

test("bad thrust values are refused with a reason and change nothing", { timeout: TEST_MS }, async () => {
  const { channel, events } = pilot;
  const bad = [
    motion(5, pilot.epoch),
    motion("fast", pilot.epoch),
    { ...motion(0.5, pilot.epoch), heave: -1.5 },
    { mode: "motion", surge: 0.5, heave: 0, yaw: 0 },
  ];
  for (const payload of bad) {
    const { status, response } = await reply(channel.push("thrust", payload, REPLY_MS), "bad thrust");
    assert.equal(status, "error", `accepted bad thrust ${JSON.stringify(payload)}: ${JSON.stringify(response)}`);
    assert.equal(typeof response?.reason, "string", `error reply needs a reason: ${JSON.stringify(response)}`);
    assert.ok(response.reason.length > 0, "reason must not be empty");
  }
  const t = await events.next("telemetry", () => true, REPLY_MS, "telemetry after bad thrust");
  assert.ok(thrustersAtZero(t) && commandAtZero(t), `a refused command moved the vehicle: ${JSON.stringify(t.command)}`);
});

test("closing the pilot's socket stops the vehicle and frees the helm", { timeout: TEST_MS }, async () => {
  // go again so there is something to stop
  const go = await reply(pilot.channel.push("thrust", motion(0.5, pilot.epoch), REPLY_MS), "thrust");
  assert.equal(go.status, "ok", `thrust refused: ${JSON.stringify(go.response)}`);
  await observer.events.next("telemetry", (t) => t.command.surge > 0, REPLY_MS, "observer sees the thrust");

  const freed = observer.events.next("helm", (h) => h.state === "free", REPLY_MS, "helm free");
  freed.catch(() => undefined);
  const stopped = observer.events.next("stopped", (s) => s.reason === "pilot_disconnected", REPLY_MS, "stopped pilot_disconnected");
  stopped.catch(() => undefined);
  clearInterval(pilot.heartbeat);
  await closeSocket(pilot.socket);
  await freed;
  await stopped;
  await observer.events.next(
    "telemetry",
    (t) => thrustersAtZero(t) && commandAtZero(t),
    REPLY_MS,
    "thrusters at zero after the pilot left",
  );
  // and the observer may take over now: granted at once
  const { status, response } = await reply(observer.channel.push("request_control", {}, REPLY_MS), "observer request_control");
  assert.equal(status, "ok", `observer could not take the free helm: ${JSON.stringify(response)}`);
  assert.equal(response.status, "granted");
});
