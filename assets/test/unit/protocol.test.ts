import { describe, expect, it } from "vitest";
import {
  cameraWithToken,
  decodeCameraStatus,
  decodeRecordingStatus,
  decodeCamera,
  decodeControlReply,
  decodeControlSettings,
  decodeControlUpdate,
  decodeFleetReply,
  decodeGrant,
  decodeHelm,
  decodeParty,
  decodeSession,
  decodePilot,
  decodeTelemetry,
  decodeThrustReply,
  decodeVehicleSnapshot,
  errorReason,
  presenceEntry,
} from "../../src/lib/protocol";
import { barGeometry } from "../../src/operator/format";
import { free } from "./helm_fixtures";

const telemetry = {
  t: 12.5,
  sent_at: 1_700_000_000_123.5,
  measurement: { depth: 1.25, heading: 3.1, roll: 0.01, pitch: -0.02, voltage: 12.1, current: 1.5 },
  sim: { x: 1, y: 2, z: 1.25, phi: 0, theta: 0, psi: 3.1, u: 0.3, v: 0, w: 0, p: 0, q: 0, r: 0 },
  command: { surge: 1, heave: 0, yaw: 0 },
  thrusters: {
    port: -0.5,
    vertical: 0,
    starboard: 0.5,
    port_us: 1250,
    vertical_us: 1500,
    starboard_us: 1750,
  },
};

const helm = free;

/** What decodeTelemetry gives for `input` when it has no fields of later servers. */
const plain = (input: Record<string, unknown>, over: Record<string, unknown> = {}): Record<string, unknown> => ({
  ...telemetry,
  manual: null,
  measurement_state: null,
  control: null,
  autopilot: null,
  estimate: null,
  link: null,
  wild_points: null,
  recording: null,
  camera_status: null,
  raw: input,
  ...over,
});

describe("decodeTelemetry", () => {
  it("accepts the documented shape (and keeps the raw payload for the plots)", () => {
    expect(decodeTelemetry(telemetry)).toEqual(plain(telemetry));
  });

  it("keeps the axes the pilot may command when the server sends them (not when null or malformed)", () => {
    const input = { ...telemetry, axes: ["surge", "sway", "heave", "yaw"] };
    expect(decodeTelemetry(input)).toEqual(plain(input, { axes: ["surge", "sway", "heave", "yaw"] }));
    expect(decodeTelemetry({ ...telemetry, axes: null })?.axes).toBeUndefined();
    expect(decodeTelemetry({ ...telemetry, axes: ["sideways"] })?.axes).toBeUndefined();
  });

  it("accepts sim: null (a real board)", () => {
    const input = { ...telemetry, sim: null };
    expect(decodeTelemetry(input)).toEqual(plain(input, { sim: null }));
  });

  it("drops unknown fields from the typed part", () => {
    const input = { ...telemetry, extra: 1, sim: { ...telemetry.sim, k: 2 } };
    expect(decodeTelemetry(input)).toEqual(plain(input));
  });

  it("reads missing or null measurements as NaN (not known) rather than dropping the sample", () => {
    const { depth: _depth, ...noDepth } = telemetry.measurement;
    const decoded = decodeTelemetry({ ...telemetry, measurement: { ...noDepth, voltage: null } });
    expect(decoded?.measurement.depth).toBeNaN();
    expect(decoded?.measurement.voltage).toBeNaN();
    expect(decoded?.measurement.heading).toBe(3.1);
  });

  it("decodes measurement_state; null unless every measurement has a known state", () => {
    const states = { depth: "initialising", heading: "valid", roll: "valid", pitch: "valid", voltage: "stale", current: "valid" };
    const input = { ...telemetry, measurement: { ...telemetry.measurement, depth: null }, measurement_state: states };
    const d = decodeTelemetry(input);
    expect(d?.measurement_state).toEqual(states);
    expect(d?.measurement.depth).toBeNaN();
    expect(decodeTelemetry({ ...telemetry, measurement_state: { ...states, depth: "maybe" } })?.measurement_state).toBeNull();
    const { current: _current, ...five } = states;
    expect(decodeTelemetry({ ...telemetry, measurement_state: five })?.measurement_state).toBeNull();
  });

  it("decodes why an engaged autopilot waits", () => {
    const waiting = "depth hold: depth is initialising (the board's depth sensor has not given consistent readings yet)";
    const d = decodeTelemetry({ ...telemetry, autopilot: { depth: { setpoint: 2, output: 0, overridden: false, waiting }, heading: null } });
    expect(d?.autopilot?.depth).toEqual({ setpoint: 2, output: 0, waiting });
  });

  it("decodes a manual command (thrusters named) as `manual`", () => {
    const decoded = decodeTelemetry({ ...telemetry, command: { port: 0.5, vertical: -1, starboard: 0 } });
    expect(decoded?.command).toBeNull();
    expect(decoded?.manual).toEqual({ port: 0.5, vertical: -1, starboard: 0 });
  });

  it("decodes the fields later servers add: control, autopilot, estimate, link, wild_points", () => {
    const input = {
      ...telemetry,
      control: { mode: "dp", gain: 0.7, lights: 100, laser: 0, tilt: 0.2, run_mode: "simulator", autopilot: { depth: 2, heading: null } },
      autopilot: { depth: { setpoint: 2, output: 0.3 }, heading: null },
      estimate: { depth: 1.2, depth_rate: 0.1, heading: 3, yaw_rate: 0.01 },
      link: { up: false, reason: "hangup: end of file on the line" },
      wild_points: { total: 4, by_field: { hdgd: 3, deap: 1, junk: "x" } },
    };
    const d = decodeTelemetry(input);
    expect(d?.control).toEqual({ mode: "dp", gain: 0.7, lights: 100, laser: 0, tilt: 0.2, run_mode: "simulator", autopilot: { depth: 2, heading: null } });
    expect(d?.autopilot).toEqual({ depth: { setpoint: 2, output: 0.3, waiting: null }, heading: null });
    expect(d?.estimate).toEqual({ depth: 1.2, depth_rate: 0.1, heading: 3, yaw_rate: 0.01 });
    expect(d?.link).toEqual({ up: false, reason: "hangup: end of file on the line" });
    expect(d?.wild_points).toEqual({ total: 4, by_field: { hdgd: 3, deap: 1 } });
  });

  it("tolerates malformed optional fields (null), partial control settings and estimates", () => {
    const d = decodeTelemetry({ ...telemetry, control: { gain: 1 }, link: { up: "yes" }, estimate: { depth: 1 }, wild_points: {} });
    expect(d?.control).toBeNull();
    expect(d?.link).toBeNull();
    expect(d?.wild_points).toBeNull();
    expect(d?.estimate?.depth).toBe(1);
    expect(d?.estimate?.yaw_rate).toBeNaN();
    const partial = decodeTelemetry({ ...telemetry, control: { mode: "motion" } });
    expect(partial?.control).toEqual({ mode: "motion", gain: null, lights: null, laser: null, tilt: null, run_mode: null, autopilot: null });
  });

  it("rejects missing, non-numeric or non-finite required fields", () => {
    expect(decodeTelemetry(null)).toBeNull();
    expect(decodeTelemetry([])).toBeNull();
    expect(decodeTelemetry({ ...telemetry, t: "1" })).toBeNull();
    expect(decodeTelemetry({ ...telemetry, sim: undefined })).toBeNull();
    expect(decodeTelemetry({ ...telemetry, sim: { x: 1 } })).toBeNull();
    expect(decodeTelemetry({ ...telemetry, measurement: 3 })).toBeNull();
    expect(
      decodeTelemetry({ ...telemetry, thrusters: { ...telemetry.thrusters, port: Number.NaN } }),
    ).toBeNull();
    expect(decodeTelemetry({ ...telemetry, command: { surge: 1, heave: 0 } })).toBeNull();
  });
});

describe("control settings replies and the camera", () => {
  it("decodes {control: C}", () => {
    expect(decodeControlUpdate({ control: { mode: "manual", gain: 0.3 } })).toEqual({
      mode: "manual", gain: 0.3, lights: null, laser: null, tilt: null, run_mode: null, autopilot: null,
    });
    expect(decodeControlUpdate({ mode: "manual" })).toBeNull();
    expect(decodeControlSettings({ mode: 1 })).toBeNull();
  });

  it("finds the camera in the snapshot, or none", () => {
    const vehicle = { id: "v", board: "simulated" };
    const mjpeg = { codec: "mjpeg", video: "/video/v/websocket", url: "http://cam:8080/?action=stream" };
    expect(decodeCamera({ vehicle, camera: mjpeg })).toEqual(mjpeg);
    const h264 = { codec: "h264", video: "/video/v/websocket", url: null };
    expect(decodeCamera({ vehicle, camera: h264 })).toEqual(h264);
    expect(decodeCamera({ vehicle, camera: null })).toBeNull();
    expect(decodeCamera({ vehicle, camera: { ...mjpeg, url: "javascript:alert(1)" } })).toBeNull();
    expect(decodeCamera({ vehicle, camera: { ...h264, video: "javascript:alert(1)" } })).toBeNull();
    expect(decodeCamera({ vehicle, camera: "/video/v.mp4" })).toBeNull();
    expect(decodeCamera({ vehicle })).toBeNull();
  });

  it("never takes another host's video socket", () => {
    const vehicle = { id: "v", board: "simulated" };
    expect(decodeCamera({ vehicle, camera: { codec: "h264", video: "//evil.example/ws", url: null } })).toBeNull();
    expect(decodeCamera({ vehicle, camera: { codec: "h264", video: "https://evil.example/ws", url: null } })).toBeNull();
    expect(decodeCamera({ vehicle, camera: { codec: "h264", video: 7, url: null } })).toBeNull();
  });
});

describe("join replies", () => {
  it("decodes the fleet reply", () => {
    expect(decodeFleetReply({ vehicles: [{ id: "neptunus-1", board: "simulated" }] })).toEqual({
      vehicles: [{ id: "neptunus-1", board: "simulated" }],
    });
    expect(decodeFleetReply({ vehicles: [] })).toEqual({ vehicles: [] });
    expect(decodeFleetReply({ vehicles: [{ id: 1, board: "x" }] })).toBeNull();
    expect(decodeFleetReply({})).toBeNull();
  });

  it("decodes the vehicle snapshot with and without telemetry and pilot", () => {
    const vehicle = { id: "neptunus-1", board: "simulated" };
    expect(decodeVehicleSnapshot({ vehicle, telemetry: null, pilot: null })).toEqual({
      vehicle,
      telemetry: null,
      pilot: null,
      helm: null,
      session: null,
      control: null,
      camera: null,
    });
    // a malformed "control" reads as none
    expect(decodeVehicleSnapshot({ vehicle, telemetry, pilot: { name: "ada" }, control: {} })).toEqual({
      vehicle,
      telemetry: plain(telemetry),
      pilot: { name: "ada" },
      helm: null,
      session: null,
      control: null,
      camera: null,
    });
    const session = { id: "c1", name: "ada", role: "pilot", mode: "local" };
    expect(decodeVehicleSnapshot({ vehicle, telemetry: null, pilot: null, helm, session, control: { mode: "motion", gain: 0.5 } })).toEqual({
      vehicle,
      telemetry: null,
      pilot: null,
      helm,
      session,
      control: { mode: "motion", gain: 0.5, lights: null, laser: null, tilt: null, run_mode: null, autopilot: null },
      camera: null,
    });
    expect(decodeVehicleSnapshot({ vehicle, telemetry: null, pilot: null, helm: { state: "x" } })).toBeNull();
    expect(
      decodeVehicleSnapshot({ vehicle, telemetry: null, pilot: null, session: { ...session, role: "admiral" } }),
    ).toBeNull();
    expect(decodeVehicleSnapshot({ vehicle, telemetry: { t: 1 }, pilot: null })).toBeNull();
    expect(decodeVehicleSnapshot({ vehicle, telemetry: null, pilot: "ada" })).toBeNull();
    expect(decodeVehicleSnapshot({ telemetry: null, pilot: null })).toBeNull();
  });

  it("decodes pilots", () => {
    expect(decodePilot(null)).toBeNull();
    expect(decodePilot(undefined)).toBeNull();
    expect(decodePilot({ name: "ada" })).toEqual({ name: "ada" });
    expect(decodePilot({ name: 3 })).toBeUndefined();
  });

  it("decodes the thrust reply (outputs; pulse widths are optional and dropped)", () => {
    const thrusters = { port: -0.5, vertical: 0, starboard: 0.5 };
    const reply = { command: telemetry.command, thrusters };
    expect(decodeThrustReply(reply)).toEqual(reply);
    expect(decodeThrustReply({ command: telemetry.command, thrusters: telemetry.thrusters })).toEqual(
      reply,
    );
    expect(decodeThrustReply({ command: telemetry.command })).toBeNull();
    // manual mode echoes the thruster command
    const manual = { command: { port: 0.5, vertical: -1, starboard: 0 }, thrusters };
    expect(decodeThrustReply({ ...manual, thrusters: telemetry.thrusters })).toEqual(manual);
    expect(decodeThrustReply({ command: { port: 0.5 }, thrusters: telemetry.thrusters })).toBeNull();
    expect(decodeThrustReply({ command: telemetry.command, thrusters: { port: 1 } })).toBeNull();
  });
});

describe("helm payloads", () => {
  const ada = { id: "c1", name: "ada", role: "pilot" };
  const main = { id: "c2", name: "main", role: "main_station" };

  it("decodes every helm state", () => {
    expect(decodeHelm(helm)).toEqual(helm);
    const piloted = { ...helm, state: "piloted", epoch: 1, pilot: { ...ada, since: 1_700_000_000_000 } };
    expect(decodeHelm(piloted)).toEqual(piloted);
    const requested = { ...piloted, state: "requested", request: { from: main, remaining_ms: 9000 } };
    expect(decodeHelm(requested)).toEqual(requested);
    const takeover = { ...piloted, state: "takeover", takeover: { by: main, countdown_ms: 3000 } };
    expect(decodeHelm(takeover)).toEqual(takeover);
  });

  it("rejects malformed helms", () => {
    expect(decodeHelm({ ...helm, state: "adrift" })).toBeNull();
    expect(decodeHelm({ ...helm, state: "piloted" })).toBeNull(); // piloted by nobody
    expect(decodeHelm({ ...helm, epoch: "1" })).toBeNull();
    expect(decodeHelm({ ...helm, request: { from: ada } })).toBeNull();
    expect(decodeHelm({ ...helm, takeover: { by: { ...main, role: "admiral" }, countdown_ms: 1 } })).toBeNull();
  });

  it("decodes grants and control replies", () => {
    const grant = {
      epoch: 3,
      pilot: { ...ada, since: 5 },
      control: { mode: "motion", gain: 0.5, command: { surge: 0, heave: 0, yaw: 0 } },
      deadman_ms: 500,
      heartbeat_ms: 100,
    };
    const settings = { lights: null, laser: null, tilt: null, run_mode: null, autopilot: null };
    expect(decodeGrant({ ...grant, control: { ...grant.control, thrusters: {} } })).toEqual({ ...grant, control: { ...grant.control, ...settings } });
    // a manual-mode grant has no motion command; a control without a mode is malformed
    expect(decodeGrant({ ...grant, control: { mode: "manual" } })?.control).toEqual({ mode: "manual", gain: null, command: null, ...settings });
    expect(decodeGrant({ ...grant, control: { gain: 0.5 } })).toBeNull();
    expect(decodeControlReply({ status: "granted", grant })).toEqual({ status: "granted", grant: { ...grant, control: { ...grant.control, ...settings } } });
    expect(decodeControlReply({ status: "pending", timeout_ms: 10000 })).toEqual({ status: "pending", timeout_ms: 10000 });
    expect(decodeControlReply({ status: "takeover", countdown_ms: 2999 })).toEqual({
      status: "takeover",
      countdown_ms: 2999,
    });
    expect(decodeControlReply({ status: "granted" })).toBeNull();
    expect(decodeControlReply({ status: "maybe" })).toBeNull();
    expect(decodeParty(ada)).toEqual(ada);
    expect(decodeParty({ name: "x" })).toBeNull();
    expect(decodeSession({ id: "c", name: "n", role: "observer", mode: "secure" })).toEqual({
      id: "c",
      name: "n",
      role: "observer",
      mode: "secure",
    });
    expect(decodeSession({ id: "c", name: "n", role: "observer", mode: "open" })).toBeNull();
  });
});

describe("errorReason", () => {
  it("uses the server's reason, else the reply as JSON", () => {
    expect(errorReason({ reason: "not_in_control" })).toBe("not_in_control");
    expect(errorReason({ reason: "" })).toBe('{"reason":""}');
    expect(errorReason({ oops: 1 })).toBe('{"oops":1}');
    expect(errorReason(undefined)).toBe("unknown error");
  });
});

describe("presenceEntry", () => {
  it("takes the name from the metas, else the key", () => {
    expect(presenceEntry("k1", { metas: [{ phx_ref: "a", name: "ada" }] })).toEqual({
      key: "k1",
      name: "ada",
      connections: 1,
      role: null,
      pilot: false,
    });
    expect(presenceEntry("bob", { metas: [{ phx_ref: "a" }, { phx_ref: "b" }] })).toEqual({
      key: "bob",
      name: "bob",
      connections: 2,
      role: null,
      pilot: false,
    });
    expect(presenceEntry("x", null)).toEqual({ key: "x", name: "x", connections: 1, role: null, pilot: false });
  });

  it("marks the pilot and reads the role", () => {
    const metas = [
      { phx_ref: "a", name: "ada", role: "pilot", pilot: false },
      { phx_ref: "b", name: "ada", role: "pilot", pilot: true },
    ];
    expect(presenceEntry("ada", { metas })).toEqual({ key: "ada", name: "ada", connections: 2, role: "pilot", pilot: true });
  });
});

describe("barGeometry", () => {
  it("fills right from the centre for forward, left for reverse, clamped", () => {
    expect(barGeometry(0)).toEqual({ left: 50, width: 0, reverse: false });
    expect(barGeometry(1)).toEqual({ left: 50, width: 50, reverse: false });
    expect(barGeometry(-0.5)).toEqual({ left: 25, width: 25, reverse: true });
    expect(barGeometry(-3)).toEqual({ left: 0, width: 50, reverse: true });
  });
});

describe("camera addresses", () => {
  const mjpeg = (url: string) => ({ codec: "mjpeg" as const, video: "/video/rov/websocket", url });
  it("adds the token to our own server's stream only", () => {
    expect(cameraWithToken(mjpeg("/camera/rov.mjpg"), "v1.a+b")).toEqual({
      codec: "mjpeg",
      video: "/video/rov/websocket?token=v1.a%2Bb",
      url: "/camera/rov.mjpg?token=v1.a%2Bb",
    });
    expect(cameraWithToken(mjpeg("/camera/rov.mjpg?x=1"), "t")?.url).toBe("/camera/rov.mjpg?x=1&token=t");
    expect(cameraWithToken(mjpeg("/camera/rov.mjpg"), null)).toEqual(mjpeg("/camera/rov.mjpg"));
    expect(cameraWithToken(mjpeg("http://cam.example/video.mjpg"), "t")?.url).toBe("http://cam.example/video.mjpg");
    expect(cameraWithToken(mjpeg("//cam.example/video.mjpg"), "t")?.url).toBe("//cam.example/video.mjpg");
    expect(cameraWithToken(null, "t")).toBeNull();
  });

  it("an H.264 camera has no <img> stream: only its video socket gets the token", () => {
    const h264 = { codec: "h264" as const, video: "/video/rov/websocket", url: null };
    expect(cameraWithToken(h264, "t")).toEqual({ codec: "h264", video: "/video/rov/websocket?token=t", url: null });
  });
});

describe("recording and camera state in telemetry", () => {
  it("decodes them, and null when absent or malformed", () => {
    expect(decodeRecordingStatus({ on: true, error: null })).toEqual({ on: true, error: null });
    expect(decodeRecordingStatus({ on: false, error: "disk full" })).toEqual({ on: false, error: "disk full" });
    expect(decodeRecordingStatus({ on: "yes" })).toBeNull();
    expect(decodeRecordingStatus(undefined)).toBeNull();
    const status = { running: true, fps: 15, error: null, state: "running", restarts: 0, codec: "h264", width: 640, height: 360 };
    expect(decodeCameraStatus(status)).toEqual(status);
    expect(decodeCameraStatus({ running: true, fps: 15, error: null })).toEqual({
      running: true, fps: 15, error: null, state: null, restarts: null, codec: null, width: null, height: null,
    });
    expect(decodeCameraStatus({ running: false, fps: 0, error: "ffmpeg is not installed" })?.error).toBe("ffmpeg is not installed");
    expect(decodeCameraStatus({ running: true })).toBeNull();
  });
});
