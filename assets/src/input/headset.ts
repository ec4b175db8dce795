/**
 * Headset input (thesis "further work": the head as a 3-DOF joystick). Head yaw relative to a
 * reference captured by the operator sets the autopilot heading; head pitch sets the camera
 * tilt. The head pose comes from WebXR where a headset is available, otherwise from
 * DeviceOrientation (a phone in a cardboard-style viewer). Thrust never comes from the
 * headset.
 *
 * Frames: a pose is a unit quaternion in WebXR's frame (right-handed, +Y up, the viewer looks
 * along −Z). Yaw is the rotation about +Y (positive turns left, as seen from above); pitch
 * about the viewer's X axis (positive looks up). A compass heading grows to the right, so
 * turning the head right by θ sets the heading setpoint to the reference heading + θ.
 */

import { wrapTwoPi } from "../lib/units";

export interface Quaternion {
  readonly x: number;
  readonly y: number;
  readonly z: number;
  readonly w: number;
}

export interface HeadAngles {
  /** rad, positive left (counter-clockwise from above) */
  readonly yaw: number;
  /** rad, positive up */
  readonly pitch: number;
}

/** Camera tilt range the server accepts (`set_tilt`), rad. */
export const MAX_TILT = Math.PI / 4;

const DEG = Math.PI / 180;

function multiply(a: Quaternion, b: Quaternion): Quaternion {
  return {
    x: a.x * b.w + a.w * b.x + a.y * b.z - a.z * b.y,
    y: a.y * b.w + a.w * b.y + a.z * b.x - a.x * b.z,
    z: a.z * b.w + a.w * b.z + a.x * b.y - a.y * b.x,
    w: a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
  };
}

/** Quaternion of intrinsic Euler angles in the order Y, X, Z (rad). */
export function quatFromEulerYXZ(x: number, y: number, z: number): Quaternion {
  const c1 = Math.cos(x / 2), s1 = Math.sin(x / 2);
  const c2 = Math.cos(y / 2), s2 = Math.sin(y / 2);
  const c3 = Math.cos(z / 2), s3 = Math.sin(z / 2);
  return {
    x: s1 * c2 * c3 + c1 * s2 * s3,
    y: c1 * s2 * c3 - s1 * c2 * s3,
    z: c1 * c2 * s3 - s1 * s2 * c3,
    w: c1 * c2 * c3 + s1 * s2 * s3,
  };
}

/**
 * The pose of a phone's rear camera from a `deviceorientation` event (alpha, beta, gamma in
 * degrees, as the event gives them) and the screen's orientation angle (degrees,
 * `screen.orientation.angle`), in the WebXR frame.
 */
export function quatFromDeviceOrientation(
  alphaDeg: number,
  betaDeg: number,
  gammaDeg: number,
  screenDeg: number,
): Quaternion {
  const device = quatFromEulerYXZ(betaDeg * DEG, alphaDeg * DEG, -gammaDeg * DEG);
  // the camera looks out of the back of the device, not out of its top
  const backCamera: Quaternion = { x: -Math.SQRT1_2, y: 0, z: 0, w: Math.SQRT1_2 };
  const half = (-screenDeg * DEG) / 2;
  const screen: Quaternion = { x: 0, y: 0, z: Math.sin(half), w: Math.cos(half) };
  return multiply(multiply(device, backCamera), screen);
}

/** Yaw and pitch (Euler YXZ) of a pose; roll is ignored. */
export function headAngles(q: Quaternion): HeadAngles {
  const n = Math.hypot(q.x, q.y, q.z, q.w) || 1;
  const x = q.x / n, y = q.y / n, z = q.z / n, w = q.w / n;
  const m13 = 2 * (x * z + w * y);
  const m23 = 2 * (y * z - w * x);
  const m33 = 1 - 2 * (x * x + y * y);
  const m31 = 2 * (x * z - w * y);
  const m11 = 1 - 2 * (y * y + z * z);
  const pitch = Math.asin(-Math.min(1, Math.max(-1, m23)));
  const yaw = Math.abs(m23) < 0.9999999 ? Math.atan2(m13, m33) : Math.atan2(-m31, m11);
  return { yaw, pitch };
}

/** The smallest signed difference a − b of two angles, in (−π, π]. */
export function angleDelta(a: number, b: number): number {
  let d = (a - b) % (2 * Math.PI);
  if (d <= -Math.PI) d += 2 * Math.PI;
  if (d > Math.PI) d -= 2 * Math.PI;
  return d;
}

export interface HeadReference {
  /** head yaw when the reference was captured */
  readonly yaw: number;
  /** the vehicle's heading then (rad, [0, 2π)) */
  readonly heading: number;
}

/** Heading setpoint (rad, [0, 2π)) for head yaw `yaw`: right of the reference adds. */
export function headingSetpoint(reference: HeadReference, yaw: number): number {
  return wrapTwoPi(reference.heading - angleDelta(yaw, reference.yaw));
}

/** Camera tilt (rad) for head pitch: the same angle, limited to ±45°. */
export function tiltFromPitch(pitch: number, max = MAX_TILT): number {
  if (!Number.isFinite(pitch)) return 0;
  return Math.min(max, Math.max(-max, pitch));
}

export interface HeadsetCommand {
  readonly heading?: number;
  readonly tilt?: number;
}

/**
 * Turns a stream of head poses into few commands: a new heading setpoint or tilt only when it
 * moved by at least `stepRad` (default 1°) since the last one sent, and no more often than
 * every `intervalMs` (default 200 ms) each.
 */
export class HeadsetFilter {
  private sentHeading: number | null = null;
  private sentTilt: number | null = null;
  private headingAt = -Infinity;
  private tiltAt = -Infinity;
  private readonly stepRad: number;
  private readonly intervalMs: number;

  constructor(stepRad = DEG, intervalMs = 200) {
    this.stepRad = stepRad;
    this.intervalMs = intervalMs;
  }

  reset(): void {
    this.sentHeading = null;
    this.sentTilt = null;
    this.headingAt = -Infinity;
    this.tiltAt = -Infinity;
  }

  update(now: number, reference: HeadReference, angles: HeadAngles): HeadsetCommand {
    const heading = headingSetpoint(reference, angles.yaw);
    const tilt = tiltFromPitch(angles.pitch);
    const out: { heading?: number; tilt?: number } = {};
    if (
      now - this.headingAt >= this.intervalMs &&
      (this.sentHeading === null || Math.abs(angleDelta(heading, this.sentHeading)) >= this.stepRad)
    ) {
      out.heading = heading;
      this.sentHeading = heading;
      this.headingAt = now;
    }
    if (
      now - this.tiltAt >= this.intervalMs &&
      (this.sentTilt === null || Math.abs(tilt - this.sentTilt) >= this.stepRad)
    ) {
      out.tilt = tilt;
      this.sentTilt = tilt;
      this.tiltAt = now;
    }
    return out;
  }
}
