/**
 * What DP holds, for the pilot: on a vehicle without a position source (no DVL or USBL) DP
 * holds depth and heading only, and the page says so beside the control mode.
 */
import type { ControlSettings } from "../lib/protocol";

/** The note to show in control mode dp without position hold, else null. */
export function dpNote(control: ControlSettings | null): string | null {
  if (control === null || control.mode !== "dp" || control.dp_holds === undefined) return null;
  return control.dp_holds.includes("position")
    ? null
    : "No position source: DP holds depth and heading only (the vehicle may drift).";
}
