/**
 * What every input device produces: a thrust demand in the current control mode, with absolute
 * values — motion axes (surge, heave, yaw, and sway on a vehicle that has it) or manual
 * thruster commands (port, vertical, starboard), each in [-1, 1] — and which device made it.
 * The page sends a demand only when it comes from the selected input mode (`accepts`) and
 * differs from the last one sent. A motion demand carries `sway` only when it is not 0 (no
 * sway and sway 0 are the same demand).
 */

import type { MotionAxes, ThrusterCommands } from "./keyboard";

export type InputMode = "keyboard" | "touch" | "gamepad" | "headset";
export const INPUT_MODES: readonly InputMode[] = ["keyboard", "touch", "gamepad", "headset"];

/** Control modes that take thrust from the pilot's sticks and keys (DP does not). */
export type StickMode = "motion" | "manual";

export type ThrustDemand =
  | { readonly kind: "motion"; readonly axes: MotionAxes }
  | { readonly kind: "manual"; readonly thrusters: ThrusterCommands };

export const NEUTRAL_MOTION: ThrustDemand = Object.freeze({
  kind: "motion",
  axes: Object.freeze({ surge: 0, heave: 0, yaw: 0 }),
});
export const NEUTRAL_MANUAL: ThrustDemand = Object.freeze({
  kind: "manual",
  thrusters: Object.freeze({ port: 0, vertical: 0, starboard: 0 }),
});

export function neutralDemand(mode: StickMode): ThrustDemand {
  return mode === "motion" ? NEUTRAL_MOTION : NEUTRAL_MANUAL;
}

export function isInputMode(value: unknown): value is InputMode {
  return typeof value === "string" && (INPUT_MODES as readonly string[]).includes(value);
}

/** Clamps to [-1, 1]; NaN (and other non-finite junk) becomes 0. */
export function clampAxis(value: number): number {
  if (Number.isNaN(value)) return 0;
  return Math.min(1, Math.max(-1, value));
}

/** Rounds to 1/1000 so that stick jitter below that does not produce new commands. */
export function quantize(value: number): number {
  const q = Math.round(clampAxis(value) * 1000) / 1000;
  return q === 0 ? 0 : q; // no negative zero on the wire
}

export function motionDemand(surge: number, heave: number, yaw: number, sway = 0): ThrustDemand {
  const axes = { surge: quantize(surge), heave: quantize(heave), yaw: quantize(yaw) };
  const w = quantize(sway);
  return { kind: "motion", axes: w === 0 ? axes : { ...axes, sway: w } };
}

/** Whether a vehicle with these body-frame axes (its snapshot's; null: not known) can sway. */
export function canSway(axes: readonly string[] | null): boolean {
  return axes !== null && axes.includes("sway");
}

export function manualDemand(port: number, vertical: number, starboard: number): ThrustDemand {
  return {
    kind: "manual",
    thrusters: { port: quantize(port), vertical: quantize(vertical), starboard: quantize(starboard) },
  };
}

export function demandEqual(a: ThrustDemand | null, b: ThrustDemand | null): boolean {
  if (a === null || b === null) return a === b;
  if (a.kind === "motion" && b.kind === "motion") {
    return (
      a.axes.surge === b.axes.surge &&
      a.axes.heave === b.axes.heave &&
      a.axes.yaw === b.axes.yaw &&
      (a.axes.sway ?? 0) === (b.axes.sway ?? 0)
    );
  }
  if (a.kind === "manual" && b.kind === "manual") {
    const x = a.thrusters;
    const y = b.thrusters;
    return x.port === y.port && x.vertical === y.vertical && x.starboard === y.starboard;
  }
  return false;
}

export function isNeutralDemand(d: ThrustDemand): boolean {
  return demandEqual(d, neutralDemand(d.kind));
}

/**
 * Whether a demand from `source` may drive the vehicle: only the selected input mode does,
 * only in a control mode that takes stick input (not DP), and the headset never sends thrust
 * (it sets the heading and the camera tilt).
 */
export function accepts(selected: InputMode, source: InputMode, controlMode: string): boolean {
  return source === selected && source !== "headset" && (controlMode === "motion" || controlMode === "manual");
}

/** The stick mode for a control mode, or null for modes without stick input (DP, unknown). */
export function stickMode(controlMode: string): StickMode | null {
  return controlMode === "motion" || controlMode === "manual" ? controlMode : null;
}
