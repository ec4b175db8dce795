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

const REPLY_MS = 3000;
const TEST_MS = 15000;

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
  assertNumbers(t.measurement, ["depth", "heading", "roll", "pitch", "voltage", "current"], `${where}.measurement`);
  assert.ok(
    t.measurement.heading >= 0 && t.measurement.heading < 2 * Math.PI,
    `${where}.measurement.heading = ${t.measurement.heading} rad outside [0, 2π)`,
  );
  assertNumbers(t.sim, ["x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r"], `${where}.sim`);
  assertNumbers(t.command, ["surge", "heave", "yaw"], `${where}.command`);
  assertThrusters(t.thrusters, `${where}.thrusters`);
}

const thrustersAtZero = (t) =>
  Math.abs(t.thrusters.port) < 1e-9 &&
  Math.abs(t.thrusters.vertical) < 1e-9 &&
  Math.abs(t.thrusters.starboard) < 1e-9;

const commandAtZero = (t) => t.command.surge === 0 && t.command.heave === 0 && t.command.yaw === 0;

// ---------------------------------------------------------------------------------------------
// Fixture: one pilot socket for the whole file, an observer socket for the control tests.

let pilot; // {socket, channel, events}
let observer;
let snapshot;

before(async () => {
  try {
    const res = await fetch(`${BASE}/api/health`, { signal: AbortSignal.timeout(2000) });
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
  // Leave the vehicle stopped, whatever happened above.
  for (const side of [pilot, observer]) {
    if (side?.channel?.state === "joined") {
      await within(REPLY_MS, "final stop", reply(side.channel.push("stop", { reason: "protocol test done" }, REPLY_MS), "stop")).catch(() => undefined);
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
  const events = recorder(channel, ["telemetry", "presence_state", "presence_diff", "pilot"]);
  pilot.channel = channel;
  pilot.events = events;
  const { status, response } = await reply(channel.join(REPLY_MS), `join ${TOPIC}`);
  assert.equal(status, "ok", `join ${TOPIC} refused: ${JSON.stringify(response)}`);
  snapshot = response;
  for (const key of ["vehicle", "telemetry", "pilot"]) {
    assert.ok(key in response, `snapshot has no "${key}": ${JSON.stringify(response)}`);
  }
  assert.equal(response.vehicle.id, VEHICLE);
  assert.equal(typeof response.vehicle.board, "string");
  if (response.telemetry !== null) assertTelemetry(response.telemetry, "snapshot.telemetry");
  assert.ok(
    response.pilot === null || typeof response.pilot?.name === "string",
    `snapshot.pilot must be null or {name}: ${JSON.stringify(response.pilot)}`,
  );
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
  // 20 Hz nominal: ask loosely for 5 samples within 2 s, with vehicle time moving forward
  const start = pilot.events.seen.telemetry.length;
  await pilot.events.next("telemetry", () => pilot.events.seen.telemetry.length >= start + 5, 2000, "5 telemetry samples");
  const recent = pilot.events.seen.telemetry.slice(start);
  recent.forEach((t, i) => assertTelemetry(t, `telemetry[${i}]`));
  for (let i = 1; i < recent.length; i++) {
    assert.ok(recent[i].t > recent[i - 1].t, `telemetry t must increase: ${recent[i - 1].t} then ${recent[i].t}`);
  }
});

test("thrust makes this client the pilot and moves the vehicle forward", { timeout: TEST_MS }, async () => {
  const { channel, events } = pilot;
  const before = events.last("telemetry");
  assert.ok(before, "no telemetry yet");
  const pilotEvent = events.next("pilot", (p) => p?.pilot?.name === NAME, 2000, `pilot event naming ${NAME}`);
  pilotEvent.catch(() => undefined);

  const { status, response } = await reply(
    channel.push("thrust", { mode: "motion", surge: 1, heave: 0, yaw: 0 }, REPLY_MS),
    "thrust",
  );
  if (status === "error" && response?.reason === "not_in_control") {
    assert.fail(
      `thrust refused with not_in_control: another client pilots ${VEHICLE} ` +
        `(snapshot pilot: ${JSON.stringify(snapshot?.pilot)}); close it and rerun`,
    );
  }
  assert.equal(status, "ok", `thrust refused: ${JSON.stringify(response)}`);
  assertNumbers(response.command, ["surge", "heave", "yaw"], "reply.command");
  assert.ok(response.command.surge > 0, `reply.command.surge = ${response.command.surge}, expected > 0`);
  assertThrusters(response.thrusters, "reply.thrusters", { pulseWidths: false });
  assert.ok(
    Math.abs(response.thrusters.port) > 0 && Math.abs(response.thrusters.starboard) > 0,
    `surge must drive port and starboard: ${JSON.stringify(response.thrusters)}`,
  );

  if (snapshot?.pilot?.name !== NAME) {
    const p = await pilotEvent;
    assert.equal(p.pilot.name, NAME);
  }

  const moved = await events.next(
    "telemetry",
    (t) => t.sim.u > before.sim.u + 0.01 || t.sim.x > before.sim.x + 0.01,
    2500,
    `sim.u or sim.x to increase from u=${before.sim.u}, x=${before.sim.x}`,
  );
  assertTelemetry(moved);
  assert.ok(moved.command.surge > 0, "telemetry command.surge should show the thrust");
});

test("another client is refused with not_in_control", { timeout: TEST_MS }, async () => {
  const { socket, opened } = openSocket(OTHER_NAME);
  observer = { socket };
  await opened;
  const channel = socket.channel(TOPIC, {});
  const events = recorder(channel, ["telemetry", "pilot", "presence_state", "presence_diff"]);
  observer.channel = channel;
  observer.events = events;
  const join = await reply(channel.join(REPLY_MS), `observer join ${TOPIC}`);
  assert.equal(join.status, "ok");
  assert.equal(join.response.pilot?.name, NAME, `observer's snapshot should name the pilot: ${JSON.stringify(join.response.pilot)}`);

  // the pilot sees the observer arrive
  await pilot.events.seenOrNext(
    "presence_diff",
    (d) => Object.entries(d?.joins ?? {}).some(([k, v]) => k === OTHER_NAME || v.metas?.some((m) => m.name === OTHER_NAME)),
    REPLY_MS,
    `presence_diff joining ${OTHER_NAME}`,
  );

  const { status, response } = await reply(
    channel.push("thrust", { mode: "motion", surge: -1, heave: 0, yaw: 0 }, REPLY_MS),
    "observer thrust",
  );
  assert.equal(status, "error", `observer's thrust was accepted: ${JSON.stringify(response)}`);
  assert.equal(response.reason, "not_in_control");
  const stop = await reply(channel.push("stop", { reason: "observer" }, REPLY_MS), "observer stop");
  assert.equal(stop.status, "error", "observer's stop must be refused too");
  assert.equal(stop.response.reason, "not_in_control");
  // and nothing changed: the pilot's surge is still commanded
  const t = await events.next("telemetry", () => true, REPLY_MS, "observer telemetry");
  assert.ok(t.command.surge > 0, `observer's refused command changed the vehicle: ${JSON.stringify(t.command)}`);
});

test("stop puts every thruster at zero", { timeout: TEST_MS }, async () => {
  const { channel, events } = pilot;
  const { status, response } = await reply(channel.push("stop", { reason: "protocol test" }, REPLY_MS), "stop");
  assert.equal(status, "ok", `stop refused: ${JSON.stringify(response)}`);
  const t = await events.next(
    "telemetry",
    (x) => thrustersAtZero(x) && commandAtZero(x),
    2000,
    "telemetry with thrusters and command at zero",
  );
  for (const k of ["port_us", "vertical_us", "starboard_us"]) {
    assert.ok(Math.abs(t.thrusters[k] - 1500) <= 1, `${k} = ${t.thrusters[k]} after stop, expected 1500 (neutral)`);
  }
});

test("bad thrust values are refused with a reason and change nothing", { timeout: TEST_MS }, async () => {
  const { channel, events } = pilot;
  const bad = [
    { mode: "motion", surge: 5, heave: 0, yaw: 0 },
    { mode: "motion", surge: "fast", heave: 0, yaw: 0 },
    { mode: "motion", surge: 0.5, heave: -1.5, yaw: 0 },
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

test("closing the pilot's socket releases control", { timeout: TEST_MS }, async () => {
  // go again so there is something to stop
  const go = await reply(pilot.channel.push("thrust", { mode: "motion", surge: 0.5, heave: 0, yaw: 0 }, REPLY_MS), "thrust");
  assert.equal(go.status, "ok", `thrust refused: ${JSON.stringify(go.response)}`);
  await observer.events.next("telemetry", (t) => t.command.surge > 0, REPLY_MS, "observer sees the thrust");

  const released = observer.events.next("pilot", (p) => p?.pilot === null, REPLY_MS, "pilot event {pilot: null}");
  released.catch(() => undefined);
  await closeSocket(pilot.socket);
  await released;
  await observer.events.next(
    "telemetry",
    (t) => thrustersAtZero(t) && commandAtZero(t),
    2000,
    "thrusters at zero after the pilot left",
  );
  // and the observer may take over now
  const { status, response } = await reply(
    observer.channel.push("stop", { reason: "protocol test takes over" }, REPLY_MS),
    "observer stop",
  );
  assert.equal(status, "ok", `observer could not command after the pilot left: ${JSON.stringify(response)}`);
});
