/**
 * The operator's setting forms. The server validates every value and its `error` reason is
 * shown beside the field; the page only turns what was typed into what the wire expects.
 */

import { degToRad } from "./units";

/**
 * A typed value for the wire: a number when the text is one (decimal comma accepted), else
 * the trimmed text itself, so that the server's reason names what was typed.
 */
export function formValue(text: string): number | string {
  const t = text.trim().replace(",", ".");
  if (t !== "" && /^[-+]?(\d+\.?\d*|\.\d+)(e[-+]?\d+)?$/i.test(t)) return Number(t);
  return text.trim();
}

/** A value typed in degrees, in radians for the wire (text that is no number stays text). */
export function formDegrees(text: string): number | string {
  const v = formValue(text);
  return typeof v === "number" ? degToRad(v) : v;
}

/**
 * Stops the operator must hear about (a beep): everything except the ones a pilot asks for
 * (releasing the helm, the stop button, a simulator reset).
 */
export function isSafetyStop(reason: string): boolean {
  return !["released", "pilot_stop", "sim_reset"].includes(reason);
}
