import { describe, expect, it } from "vitest";
import { NEUTRAL_MANUAL, NEUTRAL_MOTION } from "../../src/input/demand";
import type { ThrustDemand } from "../../src/input/demand";
import {
  DEFAULT_GAMEPAD_OPTIONS,
  GamepadArming,
  GamepadPoller,
  deadband,
  expo,
  gamepadDemand,
  padAtRest,
  pickGamepad,
  shape,
} from "../../src/input/gamepad";
import type { PadSnapshot } from "../../src/input/gamepad";

/** A standard-mapping pad: axes [LX, LY, RX, RY], LT and RT analog. */
function pad({ lx = 0, ly = 0, rx = 0, ry = 0, lt = 0, rt = 0 } = {}): PadSnapshot {
  const buttons = Array.from({ length: 17 }, () => ({ value: 0, pressed: false }));
  buttons[6] = { value: lt, pressed: lt > 0.5 };
  buttons[7] = { value: rt, pressed: rt > 0.5 };
  return { axes: [lx, ly, rx, ry], buttons };
}

const linear = { deadband: 0, expo: 0 };

describe("deadband", () => {
  it("reads 0 inside the band and rescales outside it (no jump at the edge)", () => {
    expect(deadband(0.05, 0.1)).toBe(0);
    expect(deadband(-0.1, 0.1)).toBe(0);
    expect(deadband(0.1000001, 0.1)).toBeCloseTo(0, 5);
    expect(deadband(0.55, 0.1)).toBeCloseTo(0.5);
    expect(deadband(-0.55, 0.1)).toBeCloseTo(-0.5);
    expect(deadband(1, 0.1)).toBe(1);
    expect(deadband(-1, 0.1)).toBe(-1);
  });

  it("clamps out-of-range input and treats NaN as 0", () => {
    expect(deadband(1.7, 0.1)).toBe(1);
    expect(deadband(-3, 0.1)).toBe(-1);
    expect(deadband(Number.NaN, 0.1)).toBe(0);
  });

  it("is monotonic and odd", () => {
    let prev = -Infinity;
    for (let v = -1; v <= 1.0001; v += 0.01) {
      const out = deadband(v, 0.2);
      expect(out).toBeGreaterThanOrEqual(prev);
      expect(deadband(-v, 0.2)).toBeCloseTo(-out, 12);
      prev = out;
    }
  });

  it("a zero band is the identity", () => {
    expect(deadband(0.3, 0)).toBeCloseTo(0.3);
  });
});

describe("expo", () => {
  it("keeps 0 and ±1 and softens the centre", () => {
    for (const e of [0, 0.3, 1]) {
      expect(expo(0, e)).toBe(0);
      expect(expo(1, e)).toBe(1);
      expect(expo(-1, e)).toBe(-1);
    }
    expect(expo(0.5, 0)).toBe(0.5);
    expect(expo(0.5, 1)).toBeCloseTo(0.125);
    expect(expo(0.5, 0.5)).toBeCloseTo(0.3125);
    expect(expo(-0.5, 1)).toBeCloseTo(-0.125);
  });

  it("clamps its factor to [0, 1]", () => {
    expect(expo(0.5, 5)).toBeCloseTo(0.125);
    expect(expo(0.5, -1)).toBe(0.5);
  });

  it("shape applies deadband then expo", () => {
    expect(shape(0.55, { deadband: 0.1, expo: 1 })).toBeCloseTo(0.125);
    expect(shape(0.05, DEFAULT_GAMEPAD_OPTIONS)).toBe(0);
  });
});

describe("gamepadDemand (thesis table 7.2)", () => {
  it("motion: right stick Y surge (up +), left stick Y heave (up ascends), right stick X yaw", () => {
    expect(gamepadDemand(pad({ ry: -1 }), "motion", linear)).toEqual({ kind: "motion", axes: { surge: 1, heave: 0, yaw: 0 } });
    expect(gamepadDemand(pad({ ry: 0.5 }), "motion", linear)).toEqual({ kind: "motion", axes: { surge: -0.5, heave: 0, yaw: 0 } });
    expect(gamepadDemand(pad({ ly: -1 }), "motion", linear)).toEqual({ kind: "motion", axes: { surge: 0, heave: -1, yaw: 0 } });
    expect(gamepadDemand(pad({ ly: 1 }), "motion", linear)).toEqual({ kind: "motion", axes: { surge: 0, heave: 1, yaw: 0 } });
    expect(gamepadDemand(pad({ rx: 0.75 }), "motion", linear)).toEqual({ kind: "motion", axes: { surge: 0, heave: 0, yaw: 0.75 } });
  });

  it("motion ignores the left stick's X and the triggers", () => {
    expect(gamepadDemand(pad({ lx: 1, lt: 1, rt: 1 }), "motion", linear)).toEqual(NEUTRAL_MOTION);
  });

  it("manual: right stick Y starboard, left stick Y port, LT vertical −, RT vertical + (analog [0, 1])", () => {
    expect(gamepadDemand(pad({ ry: -1 }), "manual", linear)).toEqual({ kind: "manual", thrusters: { port: 0, vertical: 0, starboard: 1 } });
    expect(gamepadDemand(pad({ ly: -0.5 }), "manual", linear)).toEqual({ kind: "manual", thrusters: { port: 0.5, vertical: 0, starboard: 0 } });
    expect(gamepadDemand(pad({ rt: 0.4 }), "manual", linear)).toEqual({ kind: "manual", thrusters: { port: 0, vertical: 0.4, starboard: 0 } });
    expect(gamepadDemand(pad({ lt: 0.7 }), "manual", linear)).toEqual({ kind: "manual", thrusters: { port: 0, vertical: -0.7, starboard: 0 } });
    expect(gamepadDemand(pad({ lt: 1, rt: 1 }), "manual", linear)).toEqual(NEUTRAL_MANUAL);
    // right stick X has no manual function
    expect(gamepadDemand(pad({ rx: 1 }), "manual", linear)).toEqual(NEUTRAL_MANUAL);
  });

  it("applies the deadband (default 0.1) to sticks and triggers", () => {
    expect(gamepadDemand(pad({ ry: -0.08, ly: 0.09, rx: 0.1 }), "motion")).toEqual(NEUTRAL_MOTION);
    expect(gamepadDemand(pad({ lt: 0.05 }), "manual")).toEqual(NEUTRAL_MANUAL);
    const d = gamepadDemand(pad({ ry: -0.55 }), "motion");
    expect(d.kind === "motion" && d.axes.surge).toBeCloseTo(0.5);
  });

  it("tolerates short axis/button arrays and junk values", () => {
    const junk: PadSnapshot = { axes: [Number.NaN], buttons: [] };
    expect(gamepadDemand(junk, "motion")).toEqual(NEUTRAL_MOTION);
    expect(gamepadDemand(junk, "manual")).toEqual(NEUTRAL_MANUAL);
  });

  it("never leaves [-1, 1] and has no negative zero", () => {
    for (const v of [-1.5, -1, -0.3, 0, 0.3, 1, 1.5]) {
      const d = gamepadDemand(pad({ lx: v, ly: v, rx: v, ry: v, lt: Math.abs(v), rt: Math.abs(v) / 2 }), "manual", linear);
      if (d.kind !== "manual") throw new Error("kind");
      for (const x of Object.values(d.thrusters)) {
        expect(Math.abs(x)).toBeLessThanOrEqual(1);
        expect(Object.is(x, -0)).toBe(false);
      }
    }
  });
});

describe("padAtRest and pickGamepad", () => {
  it("rest means every used input inside the deadband", () => {
    expect(padAtRest(pad())).toBe(true);
    expect(padAtRest(pad({ lx: 1 }))).toBe(true); // unused axis
    expect(padAtRest(pad({ ry: 0.09 }))).toBe(true);
    expect(padAtRest(pad({ ry: 0.3 }))).toBe(false);
    expect(padAtRest(pad({ rt: 0.5 }))).toBe(false);
  });

  it("picks the first connected pad, preferring the standard mapping", () => {
    const a = { ...pad(), id: "a", connected: true, mapping: "" };
    const b = { ...pad(), id: "b", connected: true, mapping: "standard" };
    const gone = { ...pad(), id: "c", connected: false, mapping: "standard" };
    expect(pickGamepad([null, a, gone, b])?.id).toBe("b");
    expect(pickGamepad([null, a])?.id).toBe("a");
    expect(pickGamepad([null, gone])).toBeNull();
    expect(pickGamepad([])).toBeNull();
  });
});

describe("GamepadArming", () => {
  it("after a disarm, a deflected stick reads neutral until the pad rests", () => {
    const arming = new GamepadArming();
    expect(arming.step(pad({ ry: -1 }), "motion", linear)).toEqual({ kind: "motion", axes: { surge: 1, heave: 0, yaw: 0 } });
    arming.disarm();
    expect(arming.step(pad({ ry: -1 }), "motion", linear)).toEqual(NEUTRAL_MOTION);
    expect(arming.isArmed).toBe(false);
    expect(arming.step(pad(), "motion", linear)).toEqual(NEUTRAL_MOTION);
    expect(arming.isArmed).toBe(true);
    expect(arming.step(pad({ ry: -1 }), "motion", linear)).toEqual({ kind: "motion", axes: { surge: 1, heave: 0, yaw: 0 } });
  });
});

describe("GamepadPoller", () => {
  function harness(mode: "motion" | "manual" = "motion") {
    let current: (Gamepad | null)[] = [];
    const demands: ThrustDemand[] = [];
    const pads: ({ id: string; armed: boolean } | null)[] = [];
    const frames: (() => void)[] = [];
    const poller = new GamepadPoller({
      source: { getGamepads: () => current },
      mode: () => mode,
      options: () => DEFAULT_GAMEPAD_OPTIONS,
      onDemand: (d) => demands.push(d),
      onPad: (p) => pads.push(p),
      requestFrame: (cb) => frames.push(cb),
      cancelFrame: () => undefined,
    });
    const set = (p: PadSnapshot | null): void => {
      current = p === null ? [] : [{ ...p, id: "Xbox pad", connected: true, mapping: "standard" } as unknown as Gamepad];
    };
    const frame = (): void => {
      const f = frames.shift();
      if (f) f();
    };
    return { poller, set, frame, demands, pads };
  }

  it("polls on animation frames and reports only changes", () => {
    const h = harness();
    h.poller.start();
    h.set(pad());
    h.frame(); // neutral at first: nothing to say
    expect(h.demands).toEqual([]);
    expect(h.pads).toEqual([{ id: "Xbox pad", armed: true }]);
    h.set(pad({ ry: -1 }));
    h.frame();
    h.frame(); // same reading: no new demand
    expect(h.demands).toEqual([{ kind: "motion", axes: { surge: 1, heave: 0, yaw: 0 } }]);
    h.set(pad());
    h.frame();
    expect(h.demands).toHaveLength(2);
    expect(h.demands[1]).toEqual(NEUTRAL_MOTION);
  });

  it("after reset a held stick must return to centre first; unplugging reads neutral", () => {
    const h = harness("manual");
    h.set(pad({ ly: -1 }));
    h.poller.poll();
    expect(h.demands).toEqual([{ kind: "manual", thrusters: { port: 1, vertical: 0, starboard: 0 } }]);
    h.poller.reset();
    h.poller.poll();
    expect(h.demands).toHaveLength(1); // still held: suppressed (neutral, and the server already stopped)
    expect(h.pads.at(-1)).toEqual({ id: "Xbox pad", armed: false });
    h.set(pad());
    h.poller.poll();
    expect(h.pads.at(-1)).toEqual({ id: "Xbox pad", armed: true });
    h.set(pad({ ly: -1 }));
    h.poller.poll();
    expect(h.demands.at(-1)).toEqual({ kind: "manual", thrusters: { port: 1, vertical: 0, starboard: 0 } });
    h.set(null);
    h.poller.poll();
    expect(h.demands.at(-1)).toEqual(NEUTRAL_MANUAL);
    expect(h.pads.at(-1)).toBeNull();
  });

  it("survives a getGamepads that throws", () => {
    const demands: ThrustDemand[] = [];
    const poller = new GamepadPoller({
      source: {
        getGamepads: () => {
          throw new Error("not allowed");
        },
      },
      mode: () => "motion",
      options: () => DEFAULT_GAMEPAD_OPTIONS,
      onDemand: (d) => demands.push(d),
      onPad: () => undefined,
      requestFrame: () => 0,
    });
    expect(() => poller.poll()).not.toThrow();
    expect(demands).toEqual([]);
  });
});
