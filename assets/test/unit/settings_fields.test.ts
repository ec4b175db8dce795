import { describe, expect, it } from "vitest";
import type { ControlSettings, VehicleSettings } from "../../src/lib/protocol";
import { SettingsFields } from "../../src/operator/settings_fields";
import type { SettingsVehicle } from "../../src/operator/settings_fields";
import { initialState } from "../../src/operator/state";
import type { OperatorState } from "../../src/operator/state";

const control: ControlSettings = { mode: "motion", gain: 0.5, lights: 0, laser: 0, tilt: 0, run_mode: "simulator", autopilot: null };

function harness(options: { refuse?: string; vehicle?: boolean } = {}) {
  let state: OperatorState = initialState("keyboard", { deadband: 0.1, expo: 0 });
  const sent: [string, unknown][] = [];
  let resets = 0;
  const answer = <T>(value: T): Promise<T> => (options.refuse ? Promise.reject(new Error(options.refuse)) : Promise.resolve(value));
  const vehicle: SettingsVehicle = {
    setControlMode: (mode) => {
      sent.push(["set_control_mode", mode]);
      return answer({ ...control, mode });
    },
    setRunMode: (mode) => {
      sent.push(["set_run_mode", mode]);
      return answer({ ...control, run_mode: mode });
    },
    setValue: (event, value) => {
      sent.push([event, value]);
      return answer({ ...control, gain: typeof value === "number" ? value : control.gain });
    },
    autopilot: (setpoints) => {
      sent.push(["autopilot", setpoints]);
      return answer(control);
    },
    setCameraRotation: (degrees) => {
      sent.push(["set_camera_rotation", degrees]);
      return answer({ camera_rotation: degrees } as VehicleSettings);
    },
  };
  const fields = new SettingsFields({
    get: () => state,
    update: (patch) => {
      state = { ...state, ...patch };
    },
    vehicle: () => (options.vehicle === false ? null : vehicle),
    resetInputs: () => void resets++,
  });
  return { fields, state: () => state, sent, resets: () => resets, settled: (): Promise<void> => new Promise((r) => setTimeout(r, 0)) };
}

describe("SettingsFields", () => {
  it("a typed value goes as typed; the field waits, then shows ✓ and the vehicle's answer becomes the page's", async () => {
    const h = harness();
    h.fields.setTyped("gain", " 0,8 ");
    expect(h.sent).toEqual([["set_gain", 0.8]]);
    expect(h.state().fields.gain).toEqual({ state: "busy", text: "…" });
    await h.settled();
    expect(h.state().fields.gain).toEqual({ state: "ok", text: "✓" });
    expect(h.state().control?.gain).toBe(0.8);
  });

  it("text that is no number goes as text, and the server's reason is shown beside the field", async () => {
    const h = harness({ refuse: "invalid_value" });
    h.fields.setTyped("lights", "bright");
    expect(h.sent).toEqual([["set_lights", "bright"]]);
    await h.settled();
    expect(h.state().fields.lights).toEqual({ state: "error", text: "invalid_value" });
    expect(h.state().control).toBeNull();
  });

  it("the camera tilt and the heading are typed in degrees, sent in radians", () => {
    const h = harness();
    h.fields.setTyped("tilt", "-30");
    h.fields.setAutopilot("heading", "set", "90");
    expect(h.sent[0]?.[0]).toBe("set_tilt");
    expect(h.sent[0]?.[1]).toBeCloseTo(-Math.PI / 6);
    const heading = h.sent[1]?.[1] as { heading: number };
    expect(heading.heading).toBeCloseTo(Math.PI / 2);
  });

  it("autopilots: a depth in metres, hold the current, or off", () => {
    const h = harness();
    h.fields.setAutopilot("depth", "set", "2.5");
    h.fields.setAutopilot("depth", "hold");
    h.fields.setAutopilot("heading", "off");
    expect(h.sent).toEqual([
      ["autopilot", { depth: 2.5 }],
      ["autopilot", { depth: "hold" }],
      ["autopilot", { heading: null }],
    ]);
  });

  it("a new control or run mode forgets held input first", async () => {
    const h = harness();
    h.fields.setControlMode("manual");
    expect(h.resets()).toBe(1);
    h.fields.setRunMode("normal");
    expect(h.resets()).toBe(2);
    await h.settled();
    expect(h.state().fields.control_mode?.state).toBe("ok");
    expect(h.state().control?.run_mode).toBe("normal");
  });

  it("a gamepad's step is a value for the wire", () => {
    const h = harness();
    h.fields.set("tilt", 0.1);
    expect(h.sent).toEqual([["set_tilt", 0.1]]);
  });

  it("the camera rotation: the vehicle's answer is the page's rotation", async () => {
    const h = harness();
    h.fields.setRotation(90);
    expect(h.state().fields.rotation?.state).toBe("busy");
    await h.settled();
    expect(h.state().rotation).toBe(90);
    expect(h.state().fields.rotation).toEqual({ state: "ok", text: "✓" });
  });

  it("without a vehicle nothing is sent and no field waits", () => {
    const h = harness({ vehicle: false });
    h.fields.setTyped("gain", "0.3");
    h.fields.setRotation(180);
    expect(h.sent).toEqual([]);
    expect(h.state().fields).toEqual({});
  });

  it("each field keeps its own status", () => {
    const h = harness();
    h.fields.mark("headset", "error", "heading: not_in_control");
    h.fields.setTyped("gain", "0.2");
    expect(h.state().fields.headset).toEqual({ state: "error", text: "heading: not_in_control" });
    expect(h.state().fields.gain?.state).toBe("busy");
  });
});
