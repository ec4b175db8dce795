/**
 * Touch input: two on-screen sticks and two buttons, multi-touch (one finger per control, any
 * number of controls at once), read through Pointer Events (touch, pen and mouse alike).
 *
 *                 motion                       manual
 *   left stick    up/down: heave (up: ascend)  up/down: port thruster (up: +)
 *   right stick   up/down: surge, left/right: yaw   up/down: starboard thruster (up: +)
 *   buttons       —                            vertical + / vertical −
 *
 * On a vehicle that can sway, motion mode uses the ArduSub layout (as the gamepad): left stick
 * up/down heave, left/right yaw; right stick up/down surge, left/right sway.
 *
 * Same directions as the gamepad (table 7.2). Values are absolute; lifting a finger returns its
 * control to 0. The page keeps the browser's own touch gestures off the pad (`touch-action:
 * none`, no selection, no long-press callout) so piloting neither scrolls nor zooms.
 */

import { deadband } from "./gamepad";
import { manualDemand, motionDemand } from "./demand";
import type { StickMode, ThrustDemand } from "./demand";

export type StickId = "left" | "right";
export type ButtonId = "up" | "down";
export type TouchControl = StickId | ButtonId;

/** Stick deflection, each in [-1, 1], y positive up. */
export interface StickVector {
  readonly x: number;
  readonly y: number;
}

export interface TouchState {
  readonly left: StickVector;
  readonly right: StickVector;
  readonly up: boolean;
  readonly down: boolean;
}

export const TOUCH_DEADBAND = 0.08;
const ZERO: StickVector = Object.freeze({ x: 0, y: 0 });
export const TOUCH_REST: TouchState = Object.freeze({ left: ZERO, right: ZERO, up: false, down: false });

/**
 * The stick vector of a finger `dx`, `dy` pixels (screen: y down) from the stick's centre on a
 * stick of `radius` pixels: limited to the unit circle, y positive up, with a small deadband
 * per axis.
 */
export function stickVector(dx: number, dy: number, radius: number): StickVector {
  if (!(radius > 0) || !Number.isFinite(dx) || !Number.isFinite(dy)) return ZERO;
  let x = dx / radius;
  let y = -dy / radius;
  const m = Math.hypot(x, y);
  if (m > 1) {
    x /= m;
    y /= m;
  }
  const fx = deadband(x, TOUCH_DEADBAND);
  const fy = deadband(y, TOUCH_DEADBAND);
  return { x: fx === 0 ? 0 : fx, y: fy === 0 ? 0 : fy };
}

/** The demand of the touch controls in control mode `mode` (`sway`: the vehicle can sway). */
export function touchDemand(state: TouchState, mode: StickMode, sway = false): ThrustDemand {
  if (mode === "motion" && sway) {
    return motionDemand(state.right.y, -state.left.y, state.left.x, state.right.x);
  }
  if (mode === "motion") {
    return motionDemand(state.right.y, -state.left.y, state.right.x);
  }
  const vertical = (state.up ? 1 : 0) - (state.down ? 1 : 0);
  return manualDemand(state.left.y, vertical, state.right.y);
}

interface Contact {
  readonly control: TouchControl;
  readonly cx: number;
  readonly cy: number;
  readonly radius: number;
}

/**
 * Which finger (pointer id) holds which control. A control is held by one finger at a time: a
 * second finger on it is ignored until the first lifts. Pure; the view feeds it pointer events.
 */
export class TouchTracker {
  private readonly contacts = new Map<number, Contact>();
  private state: TouchState = TOUCH_REST;

  get current(): TouchState {
    return this.state;
  }

  /** Fingers down now. */
  get active(): number {
    return this.contacts.size;
  }

  /**
   * A finger `id` went down on `control` at (x, y); a stick's centre is (cx, cy) with `radius`
   * (ignored for buttons). Returns false when the control is already held by another finger.
   */
  down(id: number, control: TouchControl, x: number, y: number, cx = x, cy = y, radius = 1): boolean {
    for (const [other, c] of this.contacts) {
      if (other !== id && c.control === control) return false;
    }
    this.contacts.set(id, { control, cx, cy, radius });
    this.apply(control, id, x, y);
    return true;
  }

  /** A finger moved; returns whether it holds a control. */
  move(id: number, x: number, y: number): boolean {
    const c = this.contacts.get(id);
    if (!c) return false;
    this.apply(c.control, id, x, y);
    return true;
  }

  /** A finger lifted (or was cancelled): its control returns to rest. */
  up(id: number): boolean {
    const c = this.contacts.get(id);
    if (!c) return false;
    this.contacts.delete(id);
    this.state = c.control === "left" || c.control === "right"
      ? { ...this.state, [c.control]: ZERO }
      : { ...this.state, [c.control]: false };
    return true;
  }

  /** Forget every finger (safety stop): the operator must touch again. */
  reset(): void {
    this.contacts.clear();
    this.state = TOUCH_REST;
  }

  private apply(control: TouchControl, id: number, x: number, y: number): void {
    const c = this.contacts.get(id);
    if (!c) return;
    if (control === "left" || control === "right") {
      this.state = { ...this.state, [control]: stickVector(x - c.cx, y - c.cy, c.radius) };
    } else {
      this.state = { ...this.state, [control]: true };
    }
  }
}
