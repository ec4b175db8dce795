import { describe, expect, it } from "vitest";
import { DEFAULT_MAPPING } from "../../src/input/buttons";
import { TOUCH_REST } from "../../src/input/touch";
import type { ControlSettings } from "../../src/lib/protocol";
import { HEADSET_OFF } from "../../src/operator/headset";
import { NO_LATENCY, controlModeOf, initialState, withField, withMessage, withStatus, withTelemetry, withoutMessage } from "../../src/operator/state";
import { telemetry } from "./telemetry_fixtures";

const control: ControlSettings = { mode: "manual", gain: 0.5, lights: null, laser: null, tilt: null, run_mode: null, autopilot: null };

describe("initialState", () => {
  it("starts connecting, with nothing known of the vehicle, the browser's input mode and pad options", () => {
    const s = initialState("touch", { deadband: 0.2, expo: 0.3 });
    expect(s.status).toBe("connecting");
    expect(s.inputMode).toBe("touch");
    expect(s.gamepadOptions).toEqual({ deadband: 0.2, expo: 0.3 });
    expect([s.vehicleId, s.telemetry, s.control, s.link, s.sent, s.lastStop, s.learning]).toEqual([null, null, null, null, null, null, null]);
    expect(s.helm.me).toBe("watching");
    expect(s.latency).toEqual(NO_LATENCY);
    expect(s.buttonMapping).toBe(DEFAULT_MAPPING);
    expect(s.mappingStatus.state).toBe("loading");
    expect(s.touch).toBe(TOUCH_REST);
    expect(s.headset).toBe(HEADSET_OFF);
    expect(s.message).toEqual({ text: "", kind: "info", source: null });
  });
});

describe("controlModeOf", () => {
  it("the telemetry's mode first, then the settings', then motion", () => {
    expect(controlModeOf({ telemetry: null, control: null })).toBe("motion");
    expect(controlModeOf({ telemetry: null, control })).toBe("manual");
    expect(controlModeOf({ telemetry: telemetry({ control: { ...control, mode: "dp" } }), control })).toBe("dp");
    expect(controlModeOf({ telemetry: telemetry(), control })).toBe("manual");
  });
});

describe("withStatus", () => {
  it("connected clears when the connection was lost", () => {
    expect(withStatus({ status: "disconnected", disconnectedAt: 5 }, "connected", 9)).toEqual({ status: "connected", disconnectedAt: null });
  });

  it("losing the connection notes when; reconnecting attempts keep that time", () => {
    const lost = withStatus({ status: "connected", disconnectedAt: null }, "disconnected", 100);
    expect(lost).toEqual({ status: "disconnected", disconnectedAt: 100 });
    expect(withStatus(lost, "connecting", 200)).toEqual({ status: "connecting", disconnectedAt: 100 });
    expect(withStatus({ status: "connecting", disconnectedAt: 100 }, "disconnected", 300)).toEqual({ status: "disconnected", disconnectedAt: 100 });
  });

  it("the first attempt counts from its own start", () => {
    expect(withStatus({ status: "connecting", disconnectedAt: null }, "connecting", 42)).toEqual({ status: "connecting", disconnectedAt: 42 });
  });
});

describe("fields and messages", () => {
  it("a field's status replaces only its own", () => {
    const one = withField({ fields: {} }, "gain", "busy", "…");
    const two = withField(one, "lights", "error", "out_of_range");
    expect(withField(two, "gain", "ok", "✓")).toEqual({ fields: { gain: { state: "ok", text: "✓" }, lights: { state: "error", text: "out_of_range" } } });
  });

  it("a message is cleared only by its own source", () => {
    const said = withMessage("Thrust refused", "error", "command");
    expect(said).toEqual({ message: { text: "Thrust refused", kind: "error", source: "command" } });
    expect(withoutMessage(said, "helm")).toEqual({});
    expect(withoutMessage(said, "command")).toEqual({ message: { text: "", kind: "info", source: null } });
    expect(withMessage("hello", "info").message.source).toBeNull();
  });
});

describe("withTelemetry", () => {
  const fresh = { telemetryState: "live", telemetryAgeMs: 12 } as const;

  it("takes the frame and its freshness; the control settings and link it carries replace the page's", () => {
    const link = { up: false, reason: "closed" };
    const t = telemetry({ control: { ...control, gain: 0.8 }, link });
    const patch = withTelemetry(t, fresh);
    expect(patch.telemetry).toBe(t);
    expect(patch.telemetryState).toBe("live");
    expect(patch.telemetryAgeMs).toBe(12);
    expect(patch.control?.gain).toBe(0.8);
    expect(patch.link?.up).toBe(false);
  });

  it("a frame without them leaves the page's control settings and link alone", () => {
    const patch = withTelemetry(telemetry(), fresh);
    expect("control" in patch).toBe(false);
    expect("link" in patch).toBe(false);
  });

  it("the axes it carries replace the snapshot's (an ArduSub's frame became known); none leave them", () => {
    expect(withTelemetry(telemetry({ axes: ["surge", "sway", "heave", "yaw"] }), fresh).axes).toEqual(["surge", "sway", "heave", "yaw"]);
    expect(withTelemetry(telemetry({ axes: ["surge", "heave", "yaw"] }), fresh).axes).toEqual(["surge", "heave", "yaw"]);
    expect("axes" in withTelemetry(telemetry({ axes: null }), fresh)).toBe(false);
  });
});
