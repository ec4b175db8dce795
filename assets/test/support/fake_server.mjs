// A stand-in for the Neptunus server, for developing the browser code and checking the JS test
// suites when the Elixir server is not at hand. It implements only the documented contract
// (docs/API.md: static files, /api/health, Phoenix Channels v2 on /socket/websocket with
// `fleet` and `vehicle:<id>`) with a crude planar simulated vehicle and a simplified helm (local
// mode: request/grant/answer/release, epoch stamps; no takeover, no deadman). It is NOT the reference:
// the Elixir server is. Loopback only.
//
//   node test/support/fake_server.mjs [port]          (default 4199; prints the URL)

import { readFile } from "node:fs/promises";
import { createServer } from "node:http";
import { dirname, extname, join, normalize } from "node:path";
import { fileURLToPath } from "node:url";
import { WebSocketServer } from "ws";

const here = dirname(fileURLToPath(import.meta.url));
const STATIC = join(here, "..", "..", "..", "priv", "static");
const VEHICLE = { id: "neptunus-1", board: "simulated" };
const TYPES = { ".html": "text/html; charset=utf-8", ".js": "text/javascript", ".css": "text/css", ".map": "application/json" };

export function startFakeServer(port = 4199) {
  // --- vehicle ---------------------------------------------------------------------------
  const s = { x: 0, y: 0, z: 0.5, psi: 0.3, u: 0, w: 0, r: 0 };
  let cmd = { surge: 0, heave: 0, yaw: 0 };
  let pilot = null; // {conn, name, since}
  const t0 = performance.now();
  const clamp = (v) => Math.max(-1, Math.min(1, v));
  let gain = 0.5; // docs/API.md: port = sat(k(X + M)), vertical = sat(kZ), starboard = sat(k(X − M))
  const thrusters = () => {
    const port = clamp(gain * (cmd.surge + cmd.yaw));
    const starboard = clamp(gain * (cmd.surge - cmd.yaw));
    const vertical = clamp(gain * cmd.heave);
    const us = (v) => Math.round(1500 + 500 * v);
    return { port, vertical, starboard, port_us: us(port), vertical_us: us(vertical), starboard_us: us(starboard) };
  };
  // the control state C (docs/API.md, Control); lights, laser, tilt and the autopilots never change here
  const controlState = () => ({
    mode: "motion",
    gain,
    lights: 0,
    laser: 0,
    tilt: 0,
    run_mode: "normal",
    dp_holds: null,
    autopilot: { depth: null, heading: null, position: null },
    command: { ...cmd },
    thrusters: thrusters(),
  });
  const telemetry = () => {
    const heading = ((s.psi % (2 * Math.PI)) + 2 * Math.PI) % (2 * Math.PI);
    return {
      t: (performance.now() - t0) / 1000,
      sent_at: Date.now(),
      measurement: { depth: s.z, heading, roll: 0, pitch: 0, voltage: 12, current: 0.5 },
      sim: { x: s.x, y: s.y, z: s.z, phi: 0, theta: 0, psi: s.psi, u: s.u, v: 0, w: s.w, p: 0, q: 0, r: s.r },
      command: { ...cmd },
      thrusters: thrusters(),
    };
  };
  const dt = 0.01;
  const step = setInterval(() => {
    const th = thrusters();
    s.u += dt * (0.8 * (th.port + th.starboard) / 2 - 1.5 * s.u);
    s.r += dt * (0.8 * (th.port - th.starboard) / 2 - 2 * s.r);
    s.w += dt * (0.6 * th.vertical - 2 * s.w); // NED: positive vertical thrust pushes down
    s.psi = Math.atan2(Math.sin(s.psi + dt * s.r), Math.cos(s.psi + dt * s.r)); // [-π, π)
    s.x += dt * s.u * Math.cos(s.psi);
    s.y += dt * s.u * Math.sin(s.psi);
    s.z = Math.max(0, s.z + dt * s.w);
  }, 10);

  // --- channels ----------------------------------------------------------------------------
  const conns = new Set();
  let nextId = 1;
  let nextRef = 1;
  const send = (conn, msg) => conn.ws.readyState === 1 && conn.ws.send(JSON.stringify(msg));
  const broadcast = (topic, event, payload, except) => {
    for (const c of conns) {
      const joinRef = c.joined.get(topic);
      if (joinRef !== undefined && c !== except) send(c, [joinRef, null, topic, event, payload]);
    }
  };
  const vtopic = `vehicle:${VEHICLE.id}`;
  // like the server: keyed by display name, one meta per connection
  const presenceOf = (c) => ({
    [c.name]: {
      metas: [{ phx_ref: c.phxRef, online_at: c.onlineAt, since: c.onlineAt, name: c.name, role: "pilot", pilot: pilot?.conn === c, conn: c.id }],
    },
  });
  const party = (c) => ({ id: c.id, name: c.name, role: "pilot" });
  // the helm, simplified: free → granted at once; otherwise one pending request the pilot answers
  let epoch = 0;
  let request = null; // conn
  const helm = () => ({
    state: request ? "requested" : pilot ? "piloted" : "free",
    epoch,
    pilot: pilot ? { ...party(pilot.conn), since: pilot.since } : null,
    request: request ? { from: party(request), remaining_ms: 10000 } : null,
    takeover: null,
    deadman_ms: 500,
    heartbeat_ms: 100,
    request_timeout_ms: 10000,
    takeover_ms: 3000,
  });
  const grantFor = () => ({
    epoch,
    pilot: { ...party(pilot.conn), since: pilot.since },
    control: controlState(),
    deadman_ms: 500,
    heartbeat_ms: 100,
  });
  const push = (c, event, payload) => {
    const joinRef = c.joined.get(vtopic);
    if (joinRef !== undefined) send(c, [joinRef, null, vtopic, event, payload]);
  };
  const stop = (reason) => {
    cmd = { surge: 0, heave: 0, yaw: 0 };
    broadcast(vtopic, "stopped", { reason });
  };
  const grant = (c) => {
    if (pilot) {
      stop("control_transferred");
      push(pilot.conn, "control_lost", { reason: "control_transferred" });
    }
    epoch += 1;
    pilot = { conn: c, name: c.name, since: Date.now() };
    request = null;
    push(c, "control_granted", grantFor());
    broadcast(vtopic, "helm", helm());
  };
  const isAxis = (v) => typeof v === "number" && Number.isFinite(v) && v >= -1 && v <= 1;

  const tick = setInterval(() => broadcast(vtopic, "telemetry", telemetry()), 50);

  function handle(conn, [joinRef, ref, topic, event, payload]) {
    const ok = (response) => send(conn, [joinRef, ref, topic, "phx_reply", { status: "ok", response }]);
    const error = (reason) => send(conn, [joinRef, ref, topic, "phx_reply", { status: "error", response: { reason } }]);
    if (topic === "phoenix" && event === "heartbeat") return send(conn, [null, ref, "phoenix", "phx_reply", { status: "ok", response: {} }]);
    if (event === "phx_join") {
      if (topic === "fleet") {
        conn.joined.set(topic, joinRef);
        return ok({ vehicles: [VEHICLE] });
      }
      if (topic === `log:${VEHICLE.id}`) {
        conn.joined.set(topic, joinRef);
        return ok({ vehicle: VEHICLE.id });
      }
      if (topic.startsWith("vehicle:") && topic !== vtopic) return error(`unknown vehicle: ${topic.slice(8)}`);
      if (topic !== vtopic) return error("unmatched topic");
      const rejoin = conn.joined.has(topic);
      conn.joined.set(topic, joinRef);
      conn.phxRef = `r${nextRef++}`;
      ok({
        vehicle: VEHICLE,
        telemetry: telemetry(),
        pilot: pilot ? { name: pilot.name } : null,
        helm: helm(),
        control: controlState(),
        session: { id: conn.id, name: conn.name, role: "pilot", mode: "local" },
      });
      const state = {};
      for (const c of conns) if (c.joined.has(vtopic)) Object.assign(state, presenceOf(c));
      send(conn, [joinRef, null, topic, "presence_state", state]);
      if (!rejoin) broadcast(vtopic, "presence_diff", { joins: presenceOf(conn), leaves: {} }, conn);
      return;
    }
    if (event === "phx_leave") {
      ok({});
      leave(conn, topic);
      return send(conn, [joinRef, joinRef, topic, "phx_close", {}]);
    }
    if (topic !== vtopic || !conn.joined.has(topic)) return error("unmatched topic");
    const isPilot = pilot?.conn === conn;
    switch (event) {
      case "request_control":
        if (!pilot) {
          grant(conn);
          return ok({ status: "granted", grant: grantFor() });
        }
        if (isPilot) return ok({ status: "granted", grant: grantFor() });
        if (request && request !== conn) return error("busy");
        request = conn;
        push(pilot.conn, "control_request", { from: party(conn) });
        broadcast(vtopic, "helm", helm());
        return ok({ status: "pending", timeout_ms: 10000 });
      case "answer_request": {
        if (!isPilot) return error("not_in_control");
        if (!request) return error("no_request");
        if (typeof payload?.accept !== "boolean") return error("accept must be true or false");
        const requester = request;
        if (payload.accept) {
          grant(requester);
        } else {
          request = null;
          push(requester, "request_denied", { reason: "denied" });
          broadcast(vtopic, "helm", helm());
        }
        return ok({ helm: helm() });
      }
      case "release_control":
        if (!isPilot) return error("not_in_control");
        stop("released");
        push(conn, "control_lost", { reason: "released" });
        pilot = null;
        request = null;
        broadcast(vtopic, "helm", helm());
        return ok({ helm: helm() });
      case "take_control":
        return error("forbidden");
      case "heartbeat":
        return isPilot ? ok({}) : error("not_in_control");
      case "thrust": {
        if (!isPilot) return error("not_in_control");
        const { mode, surge, heave, yaw, epoch: stamp } = payload ?? {};
        if (stamp === undefined) return error("missing field: epoch");
        if (stamp !== epoch) return error("stale_command");
        if (mode !== "motion") return error("mode must be \"motion\"");
        if (![surge, heave, yaw].every(isAxis)) return error("surge, heave and yaw must be numbers in [-1, 1]");
        cmd = { surge, heave, yaw };
        break;
      }
      case "stop":
        if (!isPilot) return error("not_in_control");
        stop(typeof payload?.reason === "string" ? payload.reason : "pilot_stop");
        break;
      case "set_gain": {
        // the settings commands' contract, shown with one of them
        if (!isPilot) return error("not_in_control");
        const v = payload?.value;
        if (typeof v !== "number" || v < 0 || v > 1) return error(`value must be a number in [0, 1], got ${JSON.stringify(v)}`);
        gain = v;
        broadcast(`log:${VEHICLE.id}`, "log", { category: "gain", level: "info", message: `gain ${v}`, at: Date.now() });
        return ok({ control: controlState() });
      }
      default:
        return error(`unknown event: ${event}`);
    }
    return ok({ command: { ...cmd }, thrusters: thrusters(), control: controlState() });
  }

  function leave(conn, topic) {
    if (!conn.joined.has(topic) || topic !== vtopic) return void conn.joined.delete(topic);
    broadcast(vtopic, "presence_diff", { joins: {}, leaves: presenceOf(conn) });
    conn.joined.delete(topic);
    if (request === conn) {
      request = null;
      broadcast(vtopic, "helm", helm());
    }
    if (pilot?.conn === conn) {
      stop("pilot_disconnected");
      pilot = null;
      const next = request;
      request = null;
      if (next) grant(next);
      else broadcast(vtopic, "helm", helm());
    }
  }

  // --- http ----------------------------------------------------------------------------------
  const http = createServer(async (req, res) => {
    const url = new URL(req.url ?? "/", "http://localhost");
    if (url.pathname === "/api/health") {
      res.writeHead(200, { "content-type": "application/json" });
      return res.end(JSON.stringify({ status: "ok", version: "0.1.0", vehicles: [VEHICLE] }));
    }
    const rel = url.pathname === "/" ? "index.html" : normalize(url.pathname).replace(/^\/+/, "");
    if (rel.startsWith("..")) return res.writeHead(400).end();
    try {
      const body = await readFile(join(STATIC, rel));
      res.writeHead(200, { "content-type": TYPES[extname(rel)] ?? "application/octet-stream" });
      res.end(body);
    } catch {
      res.writeHead(404).end("not found");
    }
  });
  const wss = new WebSocketServer({ noServer: true });
  http.on("upgrade", (req, socket, head) => {
    const url = new URL(req.url ?? "/", "http://localhost");
    if (url.pathname !== "/socket/websocket" || url.searchParams.get("vsn") !== "2.0.0") return socket.destroy();
    wss.handleUpgrade(req, socket, head, (ws) => {
      const id = nextId++;
      const name = (url.searchParams.get("name") ?? "").trim().slice(0, 40) || `guest-${1000 + id}`;
      const conn = { id: `c${id}`, ws, name, onlineAt: Date.now(), joined: new Map(), phxRef: "" };
      conns.add(conn);
      ws.on("message", (data) => {
        try {
          handle(conn, JSON.parse(String(data)));
        } catch (err) {
          console.error("fake server:", err);
        }
      });
      ws.on("close", () => {
        for (const topic of [...conn.joined.keys()]) leave(conn, topic);
        conns.delete(conn);
      });
    });
  });

  return new Promise((resolve) => {
    http.listen(port, "127.0.0.1", () => {
      const actual = http.address().port;
      resolve({
        url: `http://127.0.0.1:${actual}`,
        broadcast: (topic, event, payload) => broadcast(topic, event, payload),
        close: () =>
          new Promise((done) => {
            clearInterval(step);
            clearInterval(tick);
            for (const c of conns) c.ws.terminate();
            wss.close();
            http.close(() => done());
          }),
      });
    });
  });
}

if (process.argv[1] === fileURLToPath(import.meta.url)) {
  const port = Number(process.argv[2] ?? 4199);
  const server = await startFakeServer(port);
  console.log(`fake Neptunus server at ${server.url} (Ctrl-C to stop)`);
  const stop = () => server.close().then(() => process.exit(0));
  process.on("SIGINT", stop);
  process.on("SIGTERM", stop);
}
