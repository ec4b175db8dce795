// A dive through the official `phoenix` JS client against a Neptunus firmware image booted
// under qemu (test/firmware_test.exs): logs in as the card's admin over HTTPS (the card's own
// self-signed certificate, made on its first boot), joins the vehicle, takes the helm, thrusts
// until the telemetry shows the port thruster pushing, stops, and lets go.
//
//   NEPTUNUS_URL=https://127.0.0.1:PORT NEPTUNUS_PASSWORD=... NEPTUNUS_VEHICLE=rov node dive.mjs
//
// Prints one JSON line {"ok": true, ...}; exits 1 with the reason otherwise. Every wait has a
// deadline and the socket is closed at the end. With --hold it takes the helm, prints
// "holding" and keeps it (heartbeats) until its standard input closes.

import https from "node:https";
import { createRequire } from "node:module";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

// phoenix and ws are the pages' npm packages (assets/node_modules)
const require = createRequire(join(dirname(fileURLToPath(import.meta.url)), "../../assets/package.json"));
const { Socket } = require("phoenix");
const WebSocket = require("ws");

const BASE = process.env.NEPTUNUS_URL;
const PASSWORD = process.env.NEPTUNUS_PASSWORD;
const VEHICLE = process.env.NEPTUNUS_VEHICLE || "rov";
const WAIT_MS = Number(process.env.DIVE_WAIT_MS || 60000);

function fail(message) {
  console.log(JSON.stringify({ ok: false, error: message }));
  process.exit(1);
}

/** POST /api/login: the token. The certificate is the card's own, made on its first boot. */
function login() {
  const body = JSON.stringify({ name: "admin", password: PASSWORD });
  return new Promise((resolve, reject) => {
    const req = https.request(
      `${BASE}/api/login`,
      {
        method: "POST",
        rejectUnauthorized: false,
        headers: { "content-type": "application/json", "content-length": Buffer.byteLength(body) },
      },
      (res) => {
        let data = "";
        res.on("data", (chunk) => (data += chunk));
        res.on("end", () =>
          res.statusCode === 200
            ? resolve(JSON.parse(data).token)
            : reject(new Error(`login: HTTP ${res.statusCode} ${data}`)),
        );
      },
    );
    req.on("error", reject);
    req.setTimeout(WAIT_MS, () => req.destroy(new Error("login timed out")));
    req.end(body);
  });
}

class CardWebSocket extends WebSocket {
  constructor(url, protocols) {
    super(url, protocols, { rejectUnauthorized: false });
  }
}

function within(promise, what) {
  let timer;
  const deadline = new Promise((_, reject) => {
    timer = setTimeout(() => reject(new Error(`timed out waiting for ${what}`)), WAIT_MS);
  });
  return Promise.race([promise, deadline]).finally(() => clearTimeout(timer));
}

function reply(push, what) {
  return within(
    new Promise((resolve, reject) => {
      push
        .receive("ok", resolve)
        .receive("error", (r) => reject(new Error(`${what}: ${JSON.stringify(r)}`)))
        .receive("timeout", () => reject(new Error(`${what}: no reply`)));
    }),
    what,
  );
}

let socket;
try {
  const token = await login();
  socket = new Socket(`${BASE.replace(/^http/, "ws")}/socket`, {
    transport: CardWebSocket,
    params: { token },
    timeout: WAIT_MS,
    reconnectAfterMs: () => 1000,
  });
  await within(
    new Promise((resolve, reject) => {
      socket.onOpen(resolve);
      socket.onError((e) => reject(new Error(`WebSocket: ${e && e.message ? e.message : e}`)));
      socket.connect();
    }),
    "the WebSocket",
  );
  const channel = socket.channel(`vehicle:${VEHICLE}`, {});
  let pushing = null;
  const thrusting = new Promise((resolve) => {
    pushing = resolve;
  });
  let frames = 0;
  channel.on("telemetry", (t) => {
    frames += 1;
    if (t && t.thrusters && t.thrusters.port > 0.05) pushing(t.thrusters);
  });
  await reply(channel.join(), "join");
  const grant = await reply(channel.push("request_control", {}), "request_control");
  const epoch = grant.grant.epoch;
  if (process.argv.includes("--hold")) {
    const beat = setInterval(() => channel.push("heartbeat", {}), 200);
    console.log("holding");
    await new Promise((resolve) => {
      process.stdin.on("end", resolve);
      process.stdin.on("close", resolve);
      process.stdin.resume();
    });
    clearInterval(beat);
    socket.disconnect();
    process.exit(0);
  }
  const timer = setInterval(() => {
    channel.push("thrust", { mode: "motion", surge: 0.5, heave: 0, yaw: 0, epoch });
    channel.push("heartbeat", {});
  }, 100);
  const thrusters = await within(thrusting, "telemetry showing the thrust").finally(() =>
    clearInterval(timer),
  );
  await reply(channel.push("stop", {}), "stop").catch(() => null);
  await reply(channel.push("release_control", {}), "release_control");
  console.log(JSON.stringify({ ok: true, frames, thrusters }));
  socket.disconnect();
  process.exit(0);
} catch (e) {
  if (socket) socket.disconnect();
  fail(e.message);
}
