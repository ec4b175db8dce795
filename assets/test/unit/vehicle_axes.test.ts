// The vehicle's degrees of freedom on the page: inputs offer sway where the vehicle has it
// (an ArduSub vehicle), with the stick layout ArduSub pilots know; nowhere else.
import { describe, expect, it } from "vitest";
import { NEUTRAL_MOTION, canSway, demandEqual, motionDemand } from "../../src/input/demand";
import { gamepadDemand, padAtRest, GamepadArming } from "../../src/input/gamepad";
import type { PadSnapshot } from "../../src/input/gamepad";
import { KeyboardInput, keyboardDemand, SWAY_KEYMAP } from "../../src/input/keyboard";
import { touchDemand, TOUCH_REST } from "../../src/input/touch";
import { padLayout } from "../../src/operator/panels/input";
import { stickLabels } from "../../src/operator/touchpad";

const ARDUSUB = ["surge", "sway", "heave", "yaw"];
const THESIS = ["surge", "heave", "yaw"];
const linear = { deadband: 0, expo: 0 };
const keys = (...codes: string[]): ReadonlySet<string> => new Set(codes);

function pad({ lx = 0, ly = 0, rx = 0, ry = 0 } = {}): PadSnapshot {
  const button = { value: 0, pressed: false };
  return { axes: [lx, ly, rx, ry], buttons: Array.from({ length: 16 }, () => button) };
}

describe("a demand's sway", () => {
  it("is carried only when it is not 0: no sway and sway 0 are the same demand", () => {
    expect(motionDemand(0.5, 0, 0, 0)).toEqual({ kind: "motion", axes: { surge: 0.5, heave: 0, yaw: 0 } });
    expect(motionDemand(0, 0, 0, -0.25)).toEqual({ kind: "motion", axes: { surge: 0, heave: 0, yaw: 0, sway: -0.25 } });
    expect(demandEqual(motionDemand(0, 0, 0, 0.0001), NEUTRAL_MOTION)).toBe(true);
    expect(demandEqual(motionDemand(0, 0, 0, 0.5), NEUTRAL_MOTION)).toBe(false);
    expect(demandEqual(motionDemand(0, 0, 0, 0.5), motionDemand(0, 0, 0, -0.5))).toBe(false);
  });

  it("the vehicle sways when its axes say so; not known is the three-thruster vehicle", () => {
    expect(canSway(ARDUSUB)).toBe(true);
    expect(canSway(THESIS)).toBe(false);
    expect(canSway(null)).toBe(false);
  });
});

describe("keyboard: Z and C sway, on a vehicle that has it", () => {
  it("Z to port, C to starboard, together nothing", () => {
    expect(keyboardDemand(keys("KeyC"), "motion", true)).toEqual(motionDemand(0, 0, 0, 1));
    expect(keyboardDemand(keys("KeyZ", "KeyW"), "motion", true)).toEqual(motionDemand(1, 0, 0, -1));
    expect(keyboardDemand(keys("KeyZ", "KeyC"), "motion", true)).toEqual(NEUTRAL_MOTION);
    expect(Object.keys(SWAY_KEYMAP).sort()).toEqual(["KeyC", "KeyZ"]);
  });

  it("no sway on the three-thruster vehicle, nor in manual mode", () => {
    expect(keyboardDemand(keys("KeyC", "KeyW"), "motion")).toEqual(motionDemand(1, 0, 0));
    expect(keyboardDemand(keys("KeyC"), "manual", true)).toEqual({ kind: "manual", thrusters: { port: 0, vertical: 0, starboard: 0 } });
  });

  it("the keyboard tracks the sway keys (held, released) on a vehicle that sways only", () => {
    const seen: ReadonlySet<string>[] = [];
    const input = new KeyboardInput({ onHeld: (held) => seen.push(held), sway: () => true });
    expect(input.handleKeyDown({ code: "KeyC" })).toBe(true);
    expect(input.handleKeyUp({ code: "KeyC" })).toBe(true);
    expect(seen.map((s) => [...s])).toEqual([["KeyC"], []]);
    const thesis = new KeyboardInput({ onHeld: (held) => seen.push(held) });
    expect(thesis.handleKeyDown({ code: "KeyZ" })).toBe(false);
    expect(seen).toHaveLength(2);
  });
});

describe("gamepad: the ArduSub layout on a vehicle that sways", () => {
  it("left stick: heave ↕ (up ascends), yaw ↔; right stick: surge ↕, sway ↔", () => {
    expect(gamepadDemand(pad({ ly: -1 }), "motion", linear, true)).toEqual(motionDemand(0, -1, 0));
    expect(gamepadDemand(pad({ lx: 0.5 }), "motion", linear, true)).toEqual(motionDemand(0, 0, 0.5));
    expect(gamepadDemand(pad({ ry: -0.75 }), "motion", linear, true)).toEqual(motionDemand(0.75, 0, 0));
    expect(gamepadDemand(pad({ rx: -0.4 }), "motion", linear, true)).toEqual(motionDemand(0, 0, 0, -0.4));
  });

  it("the three-thruster vehicle keeps table 7.2 (right stick X is yaw, left X unused)", () => {
    expect(gamepadDemand(pad({ rx: -0.4 }), "motion", linear)).toEqual(motionDemand(0, 0, -0.4));
    expect(gamepadDemand(pad({ lx: 1 }), "motion", linear)).toEqual(NEUTRAL_MOTION);
  });

  it("manual mode is the same on both", () => {
    expect(gamepadDemand(pad({ ry: -1, rx: 1 }), "manual", linear, true)).toEqual(gamepadDemand(pad({ ry: -1, rx: 1 }), "manual", linear));
  });

  it("after a reset the left stick's X must rest too before the pad drives again", () => {
    expect(padAtRest(pad({ lx: 1 }), linear, true)).toBe(false);
    expect(padAtRest(pad({ lx: 1 }), linear)).toBe(true);
    const arming = new GamepadArming();
    arming.disarm();
    expect(arming.step(pad({ lx: 1 }), "motion", linear, true)).toEqual(NEUTRAL_MOTION);
    expect(arming.step(pad(), "motion", linear, true)).toEqual(NEUTRAL_MOTION);
    expect(arming.step(pad({ lx: 1 }), "motion", linear, true)).toEqual(motionDemand(0, 0, 1));
  });
});

describe("touch: the same layout on a vehicle that sways", () => {
  it("left stick heave ↕ yaw ↔, right stick surge ↕ sway ↔", () => {
    const s = { ...TOUCH_REST, left: { x: -0.5, y: 1 }, right: { x: 0.25, y: 0.5 } };
    expect(touchDemand(s, "motion", true)).toEqual(motionDemand(0.5, -1, -0.5, 0.25));
    expect(touchDemand(s, "motion")).toEqual(motionDemand(0.5, -1, 0.25));
  });
});

describe("the page says what the sticks drive", () => {
  it("touch labels and the gamepad's note follow the vehicle's axes", () => {
    expect(stickLabels("motion", true)).toEqual({ left: "heave ↕ · yaw ↔", right: "surge ↕ · sway ↔" });
    expect(stickLabels("motion", false)).toEqual({ left: "heave ↕", right: "surge ↕ · yaw ↔" });
    expect(stickLabels("manual", true)).toEqual({ left: "port ↕", right: "starboard ↕" });
    expect(padLayout(true)).toContain("sway ↔");
    expect(padLayout(false)).not.toContain("sway");
  });
});
