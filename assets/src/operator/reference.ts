/**
 * The autopilots' setpoint reference on the HUD: after a setpoint step the server's autopilot
 * tracks a rate- and acceleration-limited reference towards the setpoint (so the vehicle does
 * not jerk); the HUD shows where that reference is now while it is on its way.
 */
import type { AutopilotLoop } from "../lib/protocol";

/** How far from the setpoint the reference must be to be shown: 5 mm, 0.2°. */
export const DEPTH_TOLERANCE = 0.005;
export const HEADING_TOLERANCE = 0.2 * (Math.PI / 180);

/**
 * The loop's reference while it is more than `tolerance` (m, or rad when `angle`: the
 * difference is wrapped, so 359° and 1° are 2° apart) from the setpoint, else null (settled,
 * no reference reported, or the loop off).
 */
export function movingReference(loop: AutopilotLoop | null, tolerance: number, angle: boolean): number | null {
  if (loop === null || loop.reference === undefined) return null;
  let d = loop.setpoint - loop.reference;
  if (angle) d = Math.atan2(Math.sin(d), Math.cos(d));
  return Math.abs(d) > tolerance ? loop.reference : null;
}
