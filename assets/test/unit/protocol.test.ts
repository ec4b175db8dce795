import { describe, expect, it } from "vitest";
import {
  decodeFleetReply,
  decodePilot,
  decodeTelemetry,
  decodeThrustReply,
  decodeVehicleSnapshot,
  errorReason,
  presenceEntry,
} from "../../src/lib/protocol";
import { barGeometry } from "../../src/operator/view";

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

describe("decodeTelemetry", () => {
  it("accepts the documented shape", () => {
    expect(decodeTelemetry(telemetry)).toEqual(telemetry);
  });

  it("accepts sim: null (a real board)", () => {
    expect(decodeTelemetry({ ...telemetry, sim: null })).toEqual({ ...telemetry, sim: null });
  });

  it("drops unknown fields", () => {
    const decoded = decodeTelemetry({ ...telemetry, extra: 1, sim: { ...telemetry.sim, k: 2 } });
    expect(decoded).toEqual(telemetry);
  });

  it("rejects missing, non-numeric or non-finite fields", () => {
    expect(decodeTelemetry(null)).toBeNull();
    expect(decodeTelemetry([])).toBeNull();
    expect(decodeTelemetry({ ...telemetry, t: "1" })).toBeNull();
    expect(decodeTelemetry({ ...telemetry, sim: undefined })).toBeNull();
    expect(decodeTelemetry({ ...telemetry, sim: { x: 1 } })).toBeNull();
    const { depth: _depth, ...noDepth } = telemetry.measurement;
    expect(decodeTelemetry({ ...telemetry, measurement: noDepth })).toBeNull();
    expect(
      decodeTelemetry({ ...telemetry, thrusters: { ...telemetry.thrusters, port: Number.NaN } }),
    ).toBeNull();
    expect(decodeTelemetry({ ...telemetry, command: { surge: 1, heave: 0 } })).toBeNull();
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
    });
    // later fields (e.g. "control") are ignored
    expect(decodeVehicleSnapshot({ vehicle, telemetry, pilot: { name: "ada" }, control: {} })).toEqual({
      vehicle,
      telemetry,
      pilot: { name: "ada" },
    });
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
    expect(decodeThrustReply({ command: telemetry.command, thrusters: { port: 1 } })).toBeNull();
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
    });
    expect(presenceEntry("bob", { metas: [{ phx_ref: "a" }, { phx_ref: "b" }] })).toEqual({
      key: "bob",
      name: "bob",
      connections: 2,
    });
    expect(presenceEntry("x", null)).toEqual({ key: "x", name: "x", connections: 1 });
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
