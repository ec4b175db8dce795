// The generated decoders (src/lib/wire.gen.ts, from lib/neptunus_web/wire_schema.ex): one
// treatment of missing, null and malformed fields.
import { describe, expect, it } from "vitest";
import * as wire from "../../src/lib/wire.gen";

const telemetry = {
  t: 1.5,
  sent_at: 1_700_000_000_000,
  measurement: { depth: 1, heading: 0.5, roll: 0, pitch: 0, voltage: 12, current: null },
  sim: null,
  command: { surge: 0, heave: 0, yaw: 0 },
  thrusters: { port: 0, vertical: 0, starboard: 0, port_us: 1500, vertical_us: 1500, starboard_us: 1500 },
};

describe("a field that is not essential", () => {
  it("reads null when absent, null or of the wrong type — never undefined or NaN", () => {
    const absent = wire.decodeTelemetry(telemetry);
    expect(absent?.link).toBeNull();
    expect(absent?.measurement.current).toBeNull();
    expect(wire.decodeTelemetry({ ...telemetry, link: null })?.link).toBeNull();
    expect(wire.decodeTelemetry({ ...telemetry, link: "up" })?.link).toBeNull();
    expect(wire.decodeLinkStatus({ up: true, reason: 3 })).toEqual({
      up: true,
      reason: null,
      rtt_ms: null,
      pong_age_ms: null,
      board_uptime_ms: null,
      board_deadman_armed: null,
      firmware: null,
      detected_firmware: null,
      firmware_mismatch: null,
      commands_sent: null,
      commands_confirmed: null,
      board_settings: null,
      board_settings_pending: null,
      board_settings_reason: null,
      thrust_held: null,
      mavlink: null,
    });
  });

  it("a part of telemetry that does not decode is not known; the rest is read", () => {
    const t = wire.decodeTelemetry({ ...telemetry, control: { gain: 1 }, measurement_state: { depth: "maybe" } });
    expect(t?.control).toBeNull();
    expect(t?.measurement_state).toBeNull();
    expect(t?.measurement.depth).toBe(1);
  });
});

describe("an essential field", () => {
  it("missing, null where it may not be, or malformed: the object does not decode", () => {
    const { t: _t, ...noT } = telemetry;
    expect(wire.decodeTelemetry(noT)).toBeNull();
    expect(wire.decodeTelemetry({ ...telemetry, thrusters: null })).toBeNull();
    expect(wire.decodeTelemetry({ ...telemetry, thrusters: { ...telemetry.thrusters, port_us: 1500.5 } })).toBeNull();
    expect(wire.decodeHelm({ state: "free", epoch: "1" })).toBeNull();
  });

  it("null where the schema allows it reads null; absent where it does not is malformed", () => {
    expect(wire.decodeTelemetry(telemetry)?.sim).toBeNull();
    const { sim: _sim, ...noSim } = telemetry;
    expect(wire.decodeTelemetry(noSim)).toBeNull();
  });
});

describe("maps, lists, unions, enums", () => {
  it("a map leaves out the entries that do not decode", () => {
    expect(wire.decodeWildPoints({ total: 2, by_field: { depth: 2, junk: "x" } })?.by_field).toEqual({ depth: 2 });
  });

  it("a list with an element that does not decode does not decode", () => {
    expect(wire.decodeFleetReply({ vehicles: [{ id: "a", board: "simulated" }] })?.vehicles).toHaveLength(1);
    expect(wire.decodeFleetReply({ vehicles: [{ id: "a", board: "simulated" }, { id: 2 }] })).toBeNull();
    expect(wire.decodeMavlinkStatus({ armed: true, thrusters: [0.5, null] })?.thrusters).toEqual([0.5, null]);
  });

  it("a union is the first of its types that decodes", () => {
    expect(wire.decodePilotCommand({ surge: 1, heave: 0, yaw: 0 })).toEqual({ surge: 1, heave: 0, yaw: 0 });
    expect(wire.decodePilotCommand({ port: 1, vertical: 0, starboard: 0, extra: 1 })).toEqual({ port: 1, vertical: 0, starboard: 0 });
    expect(wire.decodePilotCommand({ port: 1 })).toBeNull();
    const pending = wire.decodeControlReply({ status: "pending", timeout_ms: 10000 });
    expect(pending?.status === "pending" ? pending.timeout_ms : null).toBe(10000);
    expect(wire.decodeControlReply({ status: "granted" })).toBeNull();
  });

  it("an enum is one of its values", () => {
    expect(wire.CONTROL_MODE_VALUES).toEqual(["motion", "manual", "dp"]);
    expect(wire.decodeControlMode("dp")).toBe("dp");
    expect(wire.decodeControlMode("hover")).toBeNull();
    expect(wire.decodeVehicleSettings({ camera_rotation: 45 })).toBeNull();
  });

  it("every event and command reply has its decoder", () => {
    expect(wire.VEHICLE_EVENT_DECODERS.stopped({ reason: "deadman" })).toEqual({ reason: "deadman" });
    expect(wire.VEHICLE_EVENT_DECODERS.presence_state({ ada: { metas: [{ phx_ref: "r" }] } })).toEqual({
      ada: { metas: [{ phx_ref: "r", name: null, role: null, pilot: null, since: null, online_at: null, conn: null, node: null }] },
    });
    expect(wire.VEHICLE_REPLY_DECODERS.clock({ now: 5 })).toEqual({ now: 5 });
    expect(wire.FLEET_EVENT_DECODERS.reachable({ id: "a" })).toBeNull();
    expect(wire.LOG_EVENT_DECODERS.log({ category: "safety", level: "warning", message: "m", at: 1, reason: "deadman" })).toEqual({
      category: "safety",
      level: "warning",
      message: "m",
      at: 1,
    });
  });
});
