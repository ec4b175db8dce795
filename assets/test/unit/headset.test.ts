import { describe, expect, it } from "vitest";
import {
  HeadsetFilter,
  MAX_TILT,
  angleDelta,
  headAngles,
  headingSetpoint,
  quatFromDeviceOrientation,
  quatFromEulerYXZ,
  tiltFromPitch,
} from "../../src/input/headset";

const DEG = Math.PI / 180;

describe("head angles from a pose", () => {
  it("identity looks straight ahead", () => {
    const a = headAngles({ x: 0, y: 0, z: 0, w: 1 });
    expect(a.yaw).toBeCloseTo(0);
    expect(a.pitch).toBeCloseTo(0);
  });

  it("yaw about +Y (left positive) and pitch about X (up positive)", () => {
    const left = headAngles(quatFromEulerYXZ(0, 30 * DEG, 0));
    expect(left.yaw).toBeCloseTo(30 * DEG);
    const up = headAngles(quatFromEulerYXZ(20 * DEG, 0, 0));
    expect(up.pitch).toBeCloseTo(20 * DEG);
    const both = headAngles(quatFromEulerYXZ(-10 * DEG, -45 * DEG, 5 * DEG));
    expect(both.yaw).toBeCloseTo(-45 * DEG);
    expect(both.pitch).toBeCloseTo(-10 * DEG);
  });

  it("normalises a non-unit quaternion", () => {
    const q = quatFromEulerYXZ(0, 30 * DEG, 0);
    const a = headAngles({ x: q.x * 3, y: q.y * 3, z: q.z * 3, w: q.w * 3 });
    expect(a.yaw).toBeCloseTo(30 * DEG);
  });
});

describe("DeviceOrientation to a head pose (phone in a viewer)", () => {
  it("a phone held upright in portrait, facing alpha 0, looks straight ahead", () => {
    const a = headAngles(quatFromDeviceOrientation(0, 90, 0, 0));
    expect(a.yaw).toBeCloseTo(0);
    expect(a.pitch).toBeCloseTo(0);
  });

  it("turning left raises alpha: yaw follows", () => {
    expect(headAngles(quatFromDeviceOrientation(30, 90, 0, 0)).yaw).toBeCloseTo(30 * DEG);
    expect(headAngles(quatFromDeviceOrientation(330, 90, 0, 0)).yaw).toBeCloseTo(-30 * DEG);
  });

  it("tilting the top of the phone back looks up", () => {
    expect(headAngles(quatFromDeviceOrientation(0, 120, 0, 0)).pitch).toBeCloseTo(30 * DEG);
    expect(headAngles(quatFromDeviceOrientation(0, 70, 0, 0)).pitch).toBeCloseTo(-20 * DEG);
  });

  it("in landscape (screen turned 90°) the same head direction gives the same yaw and pitch", () => {
    // phone rotated 90° counter-clockwise (landscape, screen angle 90): gamma −90, beta 0
    const a = headAngles(quatFromDeviceOrientation(0, 0, -90, 90));
    expect(Math.abs(a.pitch)).toBeLessThan(1e-6);
  });
});

describe("setpoints", () => {
  it("angleDelta is the short way round", () => {
    expect(angleDelta(10 * DEG, 350 * DEG)).toBeCloseTo(20 * DEG);
    expect(angleDelta(350 * DEG, 10 * DEG)).toBeCloseTo(-20 * DEG);
    expect(angleDelta(Math.PI, -Math.PI)).toBeCloseTo(0);
  });

  it("turning the head right (yaw decreasing) raises the heading setpoint, wrapped to [0, 2π)", () => {
    const ref = { yaw: 0.2, heading: 350 * DEG };
    expect(headingSetpoint(ref, 0.2)).toBeCloseTo(350 * DEG);
    expect(headingSetpoint(ref, 0.2 - 20 * DEG)).toBeCloseTo(10 * DEG);
    expect(headingSetpoint(ref, 0.2 + 90 * DEG)).toBeCloseTo(260 * DEG);
  });

  it("tilt follows the pitch within ±45°", () => {
    expect(tiltFromPitch(10 * DEG)).toBeCloseTo(10 * DEG);
    expect(tiltFromPitch(80 * DEG)).toBe(MAX_TILT);
    expect(tiltFromPitch(-80 * DEG)).toBe(-MAX_TILT);
    expect(tiltFromPitch(Number.NaN)).toBe(0);
  });
});

describe("HeadsetFilter", () => {
  const ref = { yaw: 0, heading: 0 };

  it("sends the first pose, then only steps of 1° or more, at most every 200 ms", () => {
    const f = new HeadsetFilter();
    const first = f.update(0, ref, { yaw: 0, pitch: 0 });
    expect(first.heading).toBeCloseTo(0);
    expect(first.tilt).toBeCloseTo(0);
    expect(f.update(300, ref, { yaw: -0.5 * DEG, pitch: 0.5 * DEG })).toEqual({});
    expect(f.update(350, ref, { yaw: -5 * DEG, pitch: 0 })).toEqual({ heading: expect.closeTo(5 * DEG, 6) as number });
    // too soon after the last heading
    expect(f.update(400, ref, { yaw: -10 * DEG, pitch: 0 })).toEqual({});
    expect(f.update(560, ref, { yaw: -10 * DEG, pitch: 0 }).heading).toBeCloseTo(10 * DEG);
    expect(f.update(600, ref, { yaw: -10 * DEG, pitch: 30 * DEG }).tilt).toBeCloseTo(30 * DEG);
  });

  it("reset sends again at once", () => {
    const f = new HeadsetFilter();
    f.update(0, ref, { yaw: 0, pitch: 0 });
    f.reset();
    expect(f.update(1, ref, { yaw: 0, pitch: 0 }).heading).toBeCloseTo(0);
  });
});
