import { describe, expect, it } from "vitest";
import {
  BUTTON_ACTIONS,
  ButtonRepeater,
  DEFAULT_MAPPING,
  GAIN_STEP,
  LIGHTS_STEP,
  REPEAT_MS,
  REPEATING,
  TILT_MAX,
  TILT_STEP,
  actionFor,
  assign,
  buttonCommand,
  buttonName,
  encodeMapping,
  parseMapping,
  pressedButtons,
  unassign,
  withRepeatMs,
} from "../../src/input/buttons";
import { GamepadPoller } from "../../src/input/gamepad";
import type { ControlSettings } from "../../src/lib/protocol";

function down(...buttons: number[]): boolean[] {
  const pressed = Array.from({ length: 17 }, () => false);
  for (const b of buttons) pressed[b] = true;
  return pressed;
}

const never = (): boolean => false;
const always = (): boolean => true;

describe("ButtonRepeater", () => {
  it("a press acts once, on its edge; releasing and pressing again acts again", () => {
    const r = new ButtonRepeater();
    expect(r.step(down(), 0, never, 250)).toEqual([]);
    expect(r.step(down(1), 10, never, 250)).toEqual([1]);
    for (let t = 20; t < 2000; t += 16) expect(r.step(down(1), t, never, 250)).toEqual([]);
    expect(r.step(down(), 2000, never, 250)).toEqual([]);
    expect(r.step(down(1), 2016, never, 250)).toEqual([1]);
  });

  it("a held repeating button acts again no faster than repeatMs, whatever the frame rate", () => {
    const r = new ButtonRepeater();
    r.step(down(), 0, always, 250);
    const times: number[] = [];
    for (let t = 1; t <= 1001; t += 7) if (r.step(down(15), t, always, 250).length > 0) times.push(t);
    expect(times[0]).toBe(1);
    for (let i = 1; i < times.length; i++) expect((times[i] ?? 0) - (times[i - 1] ?? 0)).toBeGreaterThanOrEqual(250);
    // and it does repeat: about 1000 / 250 times after the press
    expect(times.length).toBeGreaterThanOrEqual(4);
    expect(times.length).toBeLessThanOrEqual(5);
  });

  it("several buttons at once, each on its own edge", () => {
    const r = new ButtonRepeater();
    r.step(down(), 0, never, 250);
    expect(r.step(down(0, 3), 10, never, 250)).toEqual([0, 3]);
    expect(r.step(down(0, 3, 5), 20, never, 250)).toEqual([5]);
    expect(r.step(down(5), 30, never, 250)).toEqual([]);
  });

  it("a button held when the page starts does nothing until released", () => {
    const r = new ButtonRepeater();
    expect(r.step(down(1), 0, always, 250)).toEqual([]);
    expect(r.step(down(1), 1000, always, 250)).toEqual([]);
    expect(r.step(down(), 1010, always, 250)).toEqual([]);
    expect(r.step(down(1), 1020, always, 250)).toEqual([1]);
  });

  it("after a reset, buttons held from before do nothing (and do not repeat) until released", () => {
    const r = new ButtonRepeater();
    r.step(down(), 0, always, 250);
    expect(r.step(down(12), 10, always, 250)).toEqual([12]);
    r.reset();
    expect(r.step(down(12), 20, always, 250)).toEqual([]);
    expect(r.step(down(12), 2000, always, 250)).toEqual([]);
    expect(r.step(down(12, 2), 2010, always, 250)).toEqual([2]);
    expect(r.step(down(2), 2020, always, 250)).toEqual([]);
    expect(r.step(down(2, 12), 2030, always, 250)).toEqual([12]);
  });

  it("a reading with fewer buttons releases the missing ones", () => {
    const r = new ButtonRepeater();
    r.step([], 0, never, 250);
    expect(r.step(down(16), 10, never, 250)).toEqual([16]);
    expect(r.step([false, false], 20, never, 250)).toEqual([]);
    expect(r.step(down(16), 30, never, 250)).toEqual([16]);
  });
});

describe("pressedButtons", () => {
  it("pressed, or an analog value past half", () => {
    expect(
      pressedButtons([
        { value: 0, pressed: true },
        { value: 0.6, pressed: false },
        { value: 0.4, pressed: false },
        { value: Number.NaN, pressed: false },
      ]),
    ).toEqual([true, true, false, false]);
  });
});

describe("mapping", () => {
  it("the default maps every action to its own button of the standard layout (and the snapshot to 17), leaving LT and RT free", () => {
    const buttons = BUTTON_ACTIONS.map((a) => DEFAULT_MAPPING.actions[a]);
    expect(buttons.every((b) => typeof b === "number")).toBe(true);
    expect(new Set(buttons).size).toBe(BUTTON_ACTIONS.length);
    expect(buttons).not.toContain(6);
    expect(buttons).not.toContain(7);
    expect(actionFor(DEFAULT_MAPPING, 1)).toBe("stop");
    expect(actionFor(DEFAULT_MAPPING, 9)).toBe("request_control");
    expect(actionFor(DEFAULT_MAPPING, 7)).toBeNull();
    expect(actionFor(DEFAULT_MAPPING, 17)).toBe("snapshot");
    expect(buttonName(1)).toBe("B");
    expect(buttonName(20)).toBe("Button 20");
  });

  it("assign moves an action to a button and takes the button from its old action", () => {
    const m = assign(DEFAULT_MAPPING, "stop", 0);
    expect(m.actions.stop).toBe(0);
    expect(m.actions.depth_hold).toBeUndefined(); // A was depth hold
    expect(actionFor(m, 1)).toBeNull(); // B did stop
    expect(actionFor(m, 0)).toBe("stop");
    expect(DEFAULT_MAPPING.actions.stop).toBe(1); // the default is untouched
    expect(assign(m, "laser", 99)).toBe(m); // not a button
    expect(unassign(m, "stop").actions.stop).toBeUndefined();
  });

  it("repeat interval clamped to its range", () => {
    expect(withRepeatMs(DEFAULT_MAPPING, 10).repeatMs).toBe(REPEAT_MS.min);
    expect(withRepeatMs(DEFAULT_MAPPING, 99_999).repeatMs).toBe(REPEAT_MS.max);
    expect(withRepeatMs(DEFAULT_MAPPING, 333.4).repeatMs).toBe(333);
    expect(withRepeatMs(DEFAULT_MAPPING, Number.NaN).repeatMs).toBe(REPEAT_MS.default);
  });

  it("round-trips through the server's JSON", () => {
    const m = withRepeatMs(assign(DEFAULT_MAPPING, "laser", 7), 400);
    const json: unknown = JSON.parse(JSON.stringify(encodeMapping(m)));
    expect(parseMapping(json)).toEqual({ ok: true, mapping: m });
    expect(parseMapping(encodeMapping(unassign(m, "stop")))).toEqual({ ok: true, mapping: unassign(m, "stop") });
  });

  it("a stored mapping with anything wrong is refused whole, saying why", () => {
    const good = encodeMapping(DEFAULT_MAPPING);
    const bad: [unknown, RegExp][] = [
      [null, /not an object/],
      [[1], /not an object/],
      [{ ...good, version: 2 }, /unknown version 2/],
      [{ ...good, actions: [] }, /actions is not an object/],
      [{ ...good, repeat_ms: 5 }, /repeat_ms/],
      [{ ...good, repeat_ms: 250.5 }, /repeat_ms/],
      [{ ...good, actions: { ...good.actions, fly: 3 } }, /unknown action "fly"/],
      [{ ...good, actions: { stop: -1 } }, /stop: button must be/],
      [{ ...good, actions: { stop: 1.5 } }, /stop: button must be/],
      [{ ...good, actions: { stop: 1, laser: 1 } }, /button 1 has two actions/],
    ];
    for (const [value, reason] of bad) {
      const r = parseMapping(value);
      expect(r.ok).toBe(false);
      if (!r.ok) expect(r.reason).toMatch(reason);
    }
  });
});

const control = (over: Partial<ControlSettings> = {}): ControlSettings => ({
  mode: "motion",
  gain: 0.5,
  lights: 0,
  laser: 0,
  tilt: 0,
  run_mode: "normal",
  autopilot: { depth: null, heading: null },
  ...over,
});

describe("buttonCommand", () => {
  it("helm and input actions need no settings", () => {
    expect(buttonCommand("stop", null, 255)).toEqual({ kind: "stop" });
    expect(buttonCommand("request_control", null, 255)).toEqual({ kind: "request_control" });
    expect(buttonCommand("release_control", null, 255)).toEqual({ kind: "release_control" });
    expect(buttonCommand("input_gamepad", null, 255)).toEqual({ kind: "input_gamepad" });
    expect(buttonCommand("snapshot", null, 255)).toEqual({ kind: "snapshot" });
    expect(buttonCommand("gain_up", null, 255).kind).toBe("none");
  });

  it("steps lights, gain and tilt within their ranges", () => {
    expect(buttonCommand("lights_up", control({ lights: 0 }), 255)).toEqual({ kind: "set", field: "lights", value: LIGHTS_STEP });
    expect(buttonCommand("lights_up", control({ lights: 250 }), 255)).toEqual({ kind: "set", field: "lights", value: 255 });
    expect(buttonCommand("lights_up", control({ lights: 255 }), 255)).toEqual({ kind: "none", why: "lights is at its maximum" });
    expect(buttonCommand("lights_down", control({ lights: 10 }), 255)).toEqual({ kind: "set", field: "lights", value: 0 });
    expect(buttonCommand("lights_down", control({ lights: 0 }), 255).kind).toBe("none");
    expect(buttonCommand("gain_up", control({ gain: 0.5 }), 255)).toEqual({ kind: "set", field: "gain", value: 0.5 + GAIN_STEP });
    expect(buttonCommand("gain_up", control({ gain: 0.95 }), 255)).toEqual({ kind: "set", field: "gain", value: 1 });
    expect(buttonCommand("gain_down", control({ gain: 0.05 }), 255)).toEqual({ kind: "set", field: "gain", value: 0 });
    expect(buttonCommand("gain_down", control({ gain: 0 }), 255).kind).toBe("none");
    const up = buttonCommand("tilt_up", control({ tilt: 0 }), 255);
    expect(up.kind === "set" && Math.abs(up.value - TILT_STEP) < 1e-4).toBe(true);
    const top = buttonCommand("tilt_up", control({ tilt: TILT_MAX - 0.01 }), 255);
    expect(top.kind === "set" && top.value <= TILT_MAX && top.value > TILT_MAX - 1e-4).toBe(true);
    expect(buttonCommand("tilt_down", control({ tilt: -TILT_MAX }), 255).kind).toBe("none");
    expect(buttonCommand("tilt_centre", control({ tilt: 0.3 }), 255)).toEqual({ kind: "set", field: "tilt", value: 0 });
  });

  it("toggles lights (back to the last brightness), laser and the holds", () => {
    expect(buttonCommand("lights_toggle", control({ lights: 100 }), 100)).toEqual({ kind: "set", field: "lights", value: 0 });
    expect(buttonCommand("lights_toggle", control({ lights: 0 }), 100)).toEqual({ kind: "set", field: "lights", value: 100 });
    expect(buttonCommand("laser", control({ laser: 0 }), 1)).toEqual({ kind: "set", field: "laser", value: 255 });
    expect(buttonCommand("laser", control({ laser: 255 }), 1)).toEqual({ kind: "set", field: "laser", value: 0 });
    expect(buttonCommand("depth_hold", control(), 1)).toEqual({ kind: "autopilot", axis: "depth", action: "hold" });
    expect(buttonCommand("depth_hold", control({ autopilot: { depth: 2, heading: null } }), 1)).toEqual({ kind: "autopilot", axis: "depth", action: "off" });
    expect(buttonCommand("heading_hold", control({ autopilot: { depth: 2, heading: 1 } }), 1)).toEqual({ kind: "autopilot", axis: "heading", action: "off" });
    expect(buttonCommand("heading_hold", control({ autopilot: null }), 1)).toEqual({ kind: "autopilot", axis: "heading", action: "hold" });
  });

  it("only step actions repeat", () => {
    expect([...REPEATING].sort()).toEqual(["gain_down", "gain_up", "lights_down", "lights_up", "tilt_down", "tilt_up"]);
  });
});

describe("GamepadPoller buttons", () => {
  function setup() {
    let buttons = Array.from({ length: 17 }, () => ({ value: 0, pressed: false }));
    let now = 0;
    const presses: number[] = [];
    const poller = new GamepadPoller({
      source: {
        getGamepads: () => [
          { id: "pad", connected: true, mapping: "standard", axes: [0, 0, 0, 0], buttons } as unknown as Gamepad,
        ],
      },
      mode: () => "motion",
      options: () => ({ deadband: 0.1, expo: 0 }),
      onDemand: () => undefined,
      onPad: () => undefined,
      onPress: (b) => presses.push(b),
      repeats: (b) => b === 15,
      repeatMs: () => 200,
      nowMs: () => now,
    });
    const press = (b: number, on: boolean): void => {
      buttons = buttons.map((x, i) => (i === b ? { value: on ? 1 : 0, pressed: on } : x));
    };
    const at = (t: number): void => {
      now = t;
      poller.poll();
    };
    return { poller, presses, press, at };
  }

  it("hands each press over once; a held repeating button at most every repeatMs", () => {
    const { presses, press, at } = setup();
    at(0);
    press(1, true);
    for (let t = 10; t < 1000; t += 16) at(t);
    expect(presses).toEqual([1]);
    press(1, false);
    at(1000);
    press(15, true);
    for (let t = 1010; t <= 1410; t += 16) at(t);
    // at 1010, then ≥ 200 ms later each time: 1218, 1426 would be next
    expect(presses).toEqual([1, 15, 15]);
  });

  it("after reset (a stop) a held button does nothing until released", () => {
    const { poller, presses, press, at } = setup();
    at(0);
    press(15, true);
    at(10);
    poller.reset();
    for (let t = 20; t < 1000; t += 16) at(t);
    expect(presses).toEqual([15]);
    press(15, false);
    at(1000);
    press(15, true);
    at(1010);
    expect(presses).toEqual([15, 15]);
  });
});
