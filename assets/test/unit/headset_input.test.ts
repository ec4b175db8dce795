import { afterEach, describe, expect, it, vi } from "vitest";
import type { HeadPose } from "../../src/input/head_pose";
import { headingSetpoint } from "../../src/input/headset";
import type { Quaternion } from "../../src/input/headset";
import type { ControlSettings } from "../../src/lib/protocol";
import { HEADSET_OFF, HEADSET_SILENCE_MS, HeadsetInput } from "../../src/operator/headset";
import type { HeadsetHost, HeadsetState, HeadsetVehicle } from "../../src/operator/headset";

const control: ControlSettings = { mode: "motion", gain: 0.5, lights: null, laser: null, tilt: null, run_mode: null, autopilot: null };

/** A head turned `yaw` rad to the left and pitched `pitch` rad up (WebXR frame). */
function head(yaw: number, pitch = 0): Quaternion {
  // yaw about Y, then pitch about X
  const cy = Math.cos(yaw / 2), sy = Math.sin(yaw / 2), cp = Math.cos(pitch / 2), sp = Math.sin(pitch / 2);
  return { x: cy * sp, y: sy * cp, z: -sy * sp, w: cy * cp };
}

interface Harness {
  input: HeadsetInput;
  state: () => HeadsetState;
  pose: (q: Quaternion) => void;
  end: () => void;
  stopped: () => number;
  sent: { heading: number[]; tilt: number[] };
  results: (string | null)[];
  setSteering: (on: boolean) => void;
  setNow: (ms: number) => void;
  setHeading: (rad: number | undefined) => void;
}

function harness(options: { source?: "webxr" | "orientation"; fail?: Error; refuse?: string } = {}): Harness {
  let state: HeadsetState = HEADSET_OFF;
  let onPose: (q: Quaternion) => void = () => undefined;
  let onEnd: () => void = () => undefined;
  let stops = 0;
  let steering = true;
  let now = 0;
  let heading: number | undefined = 1;
  const sent = { heading: [] as number[], tilt: [] as number[] };
  const results: (string | null)[] = [];
  const reply = (): Promise<ControlSettings> => (options.refuse ? Promise.reject(new Error(options.refuse)) : Promise.resolve(control));
  const vehicle: HeadsetVehicle = {
    autopilot: (setpoints) => {
      sent.heading.push(setpoints.heading);
      return reply();
    },
    setValue: (_event, value) => {
      sent.tilt.push(value);
      return reply();
    },
  };
  const host: HeadsetHost = {
    get: () => state,
    update: (patch) => {
      state = { ...state, ...patch };
    },
    vehicleHeading: () => heading,
    steering: () => (steering ? vehicle : null),
    nowMs: () => now,
    onControl: () => undefined,
    onResult: (error) => results.push(error),
    startPose: (pose, end) => {
      onPose = pose;
      onEnd = end;
      if (options.fail) return Promise.reject(options.fail);
      const handle: HeadPose = { source: options.source ?? "orientation", stop: () => void stops++ };
      return Promise.resolve(handle);
    },
  };
  return {
    input: new HeadsetInput(host),
    state: () => state,
    pose: (q) => onPose(q),
    end: () => onEnd(),
    stopped: () => stops,
    sent,
    results,
    setSteering: (on) => void (steering = on),
    setNow: (ms) => void (now = ms),
    setHeading: (rad) => void (heading = rad),
  };
}

const flush = (): Promise<void> => new Promise((resolve) => setImmediate(resolve));

afterEach(() => {
  vi.useRealTimers();
});

describe("HeadsetInput", () => {
  it("starts the pose source and says which; the first pose names the sensor", async () => {
    const h = harness();
    await h.input.start();
    expect(h.state()).toMatchObject({ status: "orientation", message: "waiting for the orientation sensor…" });
    h.pose(head(0));
    expect(h.state()).toMatchObject({ status: "orientation", message: "orientation sensor", angles: { yaw: 0, pitch: 0 } });
    h.input.stop();
    const w = harness({ source: "webxr" });
    await w.input.start();
    expect(w.state()).toMatchObject({ status: "webxr", message: "WebXR headset" });
  });

  it("a source that cannot start is an error with its reason", async () => {
    const h = harness({ fail: new Error("WebXR and DeviceOrientation are unavailable") });
    await h.input.start();
    expect(h.state()).toMatchObject({ status: "error", message: "WebXR and DeviceOrientation are unavailable" });
  });

  it("a source that never reports a pose is an error after HEADSET_SILENCE_MS", async () => {
    vi.useFakeTimers();
    const silent = harness();
    await silent.input.start();
    vi.advanceTimersByTime(HEADSET_SILENCE_MS);
    expect(silent.state().status).toBe("error");

    const live = harness();
    await live.input.start();
    live.pose(head(0.1));
    vi.advanceTimersByTime(HEADSET_SILENCE_MS);
    expect(live.state().status).toBe("orientation");
  });

  it("stop ends the source, cancels the silence check and forgets the reference", async () => {
    vi.useFakeTimers();
    const h = harness();
    await h.input.start();
    h.pose(head(0));
    h.input.capture();
    h.input.stop();
    expect(h.stopped()).toBe(1);
    expect(h.state()).toMatchObject({ status: "off", message: "", reference: null, angles: null });
    vi.advanceTimersByTime(HEADSET_SILENCE_MS);
    expect(h.state().status).toBe("off");
  });

  it("the source ending on its own says so", async () => {
    const h = harness({ source: "webxr" });
    await h.input.start();
    h.end();
    expect(h.state()).toMatchObject({ status: "off", message: "the headset session ended" });
  });

  it("capture needs a head pose and the vehicle's heading", async () => {
    const h = harness();
    await h.input.start();
    h.input.capture();
    expect(h.state()).toMatchObject({ reference: null, message: "no head pose or vehicle heading to take as reference yet" });
    h.pose(head(0.2));
    h.setHeading(undefined);
    h.input.capture();
    expect(h.state().reference).toBeNull();
    h.setHeading(Number.NaN);
    h.input.capture();
    expect(h.state().reference).toBeNull();
    h.setHeading(1);
    h.input.capture();
    expect(h.state()).toMatchObject({ reference: { heading: 1 }, message: "reference set: turn your head to steer" });
    expect(h.state().reference?.yaw).toBeCloseTo(0.2, 9);
  });

  it("poses steer only with a reference and a vehicle to steer", async () => {
    const h = harness();
    await h.input.start();
    h.pose(head(0));
    expect(h.sent).toEqual({ heading: [], tilt: [] });
    h.input.capture();
    h.setSteering(false);
    h.pose(head(0.3));
    expect(h.sent).toEqual({ heading: [], tilt: [] });
    h.setSteering(true);
    h.pose(head(0.3, 0.1));
    expect(h.sent.heading).toHaveLength(1);
    expect(h.sent.heading[0]).toBeCloseTo(headingSetpoint({ yaw: 0, heading: 1 }, 0.3), 9);
    expect(h.sent.tilt).toHaveLength(1);
    expect(h.sent.tilt[0]).toBeCloseTo(0.1, 6);
    expect(h.state().lastHeading).toBe(h.sent.heading[0]);
    expect(h.state().lastTilt).toBe(h.sent.tilt[0]);
    await flush();
    expect(h.results).toEqual([null]);
    // the same pose again, later: nothing new to send
    h.setNow(1000);
    h.pose(head(0.3, 0.1));
    expect(h.sent.heading).toHaveLength(1);
  });

  it("a refused setpoint is shown with what was refused", async () => {
    const h = harness({ refuse: "not_in_control" });
    await h.input.start();
    h.pose(head(0));
    h.input.capture();
    h.pose(head(0.3, 0.1));
    await flush();
    expect(h.results).toEqual(["heading: not_in_control", "tilt: not_in_control"]);
  });
});
