// A stand-in for the Neptunus server, for developing the browser code and checking the JS test
// suites when the Elixir server is not at hand. It implements only the documented contract
// (docs/API.md: static files, /api/health, Phoenix Channels v2 on /socket/websocket with
// `fleet` and `vehicle:<id>`) with a crude planar simulated vehicle. It is NOT the reference:
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
  let pilot = null; // {conn, name}
  const t0 = performance.now();
  const clamp = (v) => Math.max(-1, Math.min(1, v));
  const GAIN = 0.5; // docs/API.md: port = sat(k(X + M)), vertical = sat(kZ), starboard = sat(k(X − M))
  const thrusters = () => {
    const port = clamp(GAIN * (cmd.surge + cmd.yaw));
    const starboard = clamp(GAIN * (cmd.surge - cmd.yaw));
    const vertical = clamp(GAIN * cmd.heave);
    const us = (v) => Math.round(1500 + 500 * v);
    return { port, vertical, starboard, port_us: us(port), vertical_us: us(vertical), starboard_us: us(starboard) };
  };
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
  const presenceOf = (c) => ({ [c.name]: { metas: [{ phx_ref: c.phxRef, online_at: c.onlineAt }] } });
  const setPilot = (p) => {
    pilot = p;
    broadcast(vtopic, "pilot", { pilot: p ? { name: p.name } : null });
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
      if (topic.startsWith("vehicle:") && topic !== vtopic) return error(`unknown vehicle: ${topic.slice(8)}`);
      if (topic !== vtopic) return error("unmatched topic");
      const rejoin = conn.joined.has(topic);
      conn.joined.set(topic, joinRef);
      conn.phxRef = `r${nextRef++}`;
      ok({
        vehicle: VEHICLE,
        telemetry: telemetry(),
        pilot: pilot ? { name: pilot.name } : null,
        control: { command: { ...cmd }, thrusters: thrusters(), gain: GAIN },
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
    if (event !== "thrust" && event !== "stop") return error(`unknown event: ${event}`);
    if (pilot && pilot.conn !== conn) return error("not_in_control");
    if (event === "thrust") {
      const { mode, surge, heave, yaw } = payload ?? {};
      if (mode !== "motion") return error("mode must be \"motion\"");
      if (![surge, heave, yaw].every(isAxis)) return error("surge, heave and yaw must be numbers in [-1, 1]");
      cmd = { surge, heave, yaw };
    } else {
      cmd = { surge: 0, heave: 0, yaw: 0 };
      broadcast(vtopic, "stopped", { reason: typeof payload?.reason === "string" ? payload.reason : "pilot_stop" });
    }
    if (!pilot) setPilot({ conn, name: conn.name });
    const { port, vertical, starboard } = thrusters(); // like the server: outputs only
    return ok({ command: { ...cmd }, thrusters: { port, vertical, starboard } });
  }

  function leave(conn, topic) {
    if (!conn.joined.delete(topic) || topic !== vtopic) return;
    broadcast(vtopic, "presence_diff", { joins: {}, leaves: presenceOf(conn) });
    if (pilot?.conn === conn) {
      cmd = { surge: 0, heave: 0, yaw: 0 };
      broadcast(vtopic, "stopped", { reason: "pilot_disconnected" });
      setPilot(null);
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
      const conn = { ws, name, onlineAt: Date.now(), joined: new Map(), phxRef: "" };
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
