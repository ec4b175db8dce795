/**
 * What DP holds, for the pilot: without a valid position (no DVL or USBL, or none of them
 * usable now) DP holds depth and heading only, and the page says so beside the control mode
 * (the map panel says why there is no position).
 */
import type { ControlSettings } from "../lib/protocol";

/** The note to show in control mode dp without position hold, else null. */
export function dpNote(control: ControlSettings | null): string | null {
  if (control === null || control.mode !== "dp" || control.dp_holds === undefined) return null;
  return control.dp_holds.includes("position")
    ? null
    : "No valid position: DP holds depth and heading only (the vehicle may drift).";
}
