import { describe, expect, it } from "vitest";
import { NEUTRAL_MANUAL, NEUTRAL_MOTION } from "../../src/input/demand";
import { TOUCH_REST, TouchTracker, stickVector, touchDemand } from "../../src/input/touch";

describe("stickVector", () => {
  it("y is positive up (screen y grows down), scaled by the radius", () => {
    expect(stickVector(0, -50, 100).y).toBeCloseTo((0.5 - 0.08) / 0.92);
    expect(stickVector(0, 100, 100)).toEqual({ x: 0, y: -1 });
    expect(stickVector(100, 0, 100)).toEqual({ x: 1, y: 0 });
  });

  it("limits the deflection to the unit circle", () => {
    const v = stickVector(300, -400, 100);
    expect(Math.hypot(v.x, v.y)).toBeLessThanOrEqual(1.0000001);
    expect(v.x).toBeCloseTo(((0.6 - 0.08) / 0.92));
    expect(v.y).toBeCloseTo(((0.8 - 0.08) / 0.92));
  });

  it("has a small deadband and rejects junk", () => {
    expect(stickVector(3, -4, 100)).toEqual({ x: 0, y: 0 });
    expect(stickVector(10, 10, 0)).toEqual({ x: 0, y: 0 });
    expect(stickVector(Number.NaN, 10, 100)).toEqual({ x: 0, y: 0 });
  });
});

describe("touchDemand", () => {
  it("motion: right stick surge (up +) and yaw (right +), left stick heave (up ascends)", () => {
    const s = { ...TOUCH_REST, right: { x: 0.5, y: 1 }, left: { x: 0.9, y: 1 } };
    expect(touchDemand(s, "motion")).toEqual({ kind: "motion", axes: { surge: 1, heave: -1, yaw: 0.5 } });
    expect(touchDemand(TOUCH_REST, "motion")).toEqual(NEUTRAL_MOTION);
  });

  it("manual: left stick port, right stick starboard, buttons vertical ±", () => {
    expect(touchDemand({ ...TOUCH_REST, left: { x: 0, y: 0.5 }, right: { x: 1, y: -1 } }, "manual")).toEqual({
      kind: "manual",
      thrusters: { port: 0.5, vertical: 0, starboard: -1 },
    });
    expect(touchDemand({ ...TOUCH_REST, up: true }, "manual")).toEqual({ kind: "manual", thrusters: { port: 0, vertical: 1, starboard: 0 } });
    expect(touchDemand({ ...TOUCH_REST, down: true }, "manual")).toEqual({ kind: "manual", thrusters: { port: 0, vertical: -1, starboard: 0 } });
    expect(touchDemand({ ...TOUCH_REST, up: true, down: true }, "manual")).toEqual(NEUTRAL_MANUAL);
  });
});

describe("TouchTracker (multi-touch)", () => {
  it("tracks one finger per stick, independently", () => {
    const t = new TouchTracker();
    // left stick centred at (100, 500), right at (900, 500), radius 100
    expect(t.down(1, "left", 100, 500, 100, 500, 100)).toBe(true);
    expect(t.down(2, "right", 900, 500, 900, 500, 100)).toBe(true);
    expect(t.active).toBe(2);
    t.move(1, 100, 400); // left up
    t.move(2, 1000, 500); // right, right
    expect(t.current.left).toEqual({ x: 0, y: 1 });
    expect(t.current.right).toEqual({ x: 1, y: 0 });
    // lifting one finger leaves the other stick alone
    expect(t.up(1)).toBe(true);
    expect(t.current.left).toEqual({ x: 0, y: 0 });
    expect(t.current.right).toEqual({ x: 1, y: 0 });
    expect(t.up(1)).toBe(false);
  });

  it("ignores a second finger on a held control and moves of unknown fingers", () => {
    const t = new TouchTracker();
    t.down(1, "right", 900, 400, 900, 500, 100);
    expect(t.down(2, "right", 950, 500, 900, 500, 100)).toBe(false);
    expect(t.move(2, 0, 0)).toBe(false);
    expect(t.current.right).toEqual({ x: 0, y: 1 });
    // the same finger going down again (a lost pointerup) takes the control over
    expect(t.down(1, "right", 900, 500, 900, 500, 100)).toBe(true);
    expect(t.current.right).toEqual({ x: 0, y: 0 });
  });

  it("buttons are held while touched", () => {
    const t = new TouchTracker();
    t.down(5, "up", 10, 10);
    t.down(6, "left", 100, 400, 100, 500, 100);
    expect(t.current.up).toBe(true);
    t.up(5);
    expect(t.current.up).toBe(false);
    expect(t.current.left.y).toBe(1);
  });

  it("reset forgets every finger: later moves change nothing", () => {
    const t = new TouchTracker();
    t.down(1, "left", 100, 400, 100, 500, 100);
    t.down(2, "down", 0, 0);
    t.reset();
    expect(t.current).toEqual(TOUCH_REST);
    expect(t.active).toBe(0);
    expect(t.move(1, 100, 300)).toBe(false);
    expect(t.current).toEqual(TOUCH_REST);
  });
});
