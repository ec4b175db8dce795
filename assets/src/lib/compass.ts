/**
 * The compass tape of the HUD: which ticks to draw around the current heading. Pure; degrees
 * (this is display code).
 */

export interface CompassTick {
  /** the tick's heading, 0..359 */
  readonly deg: number;
  /** degrees right of the centre (negative: left), within ±span/2 */
  readonly offset: number;
  readonly major: boolean;
  /** "N", "E", "S", "W", "NE"…, or the heading for other majors; null for minor ticks */
  readonly label: string | null;
}

const CARDINALS: Readonly<Record<number, string>> = {
  0: "N", 45: "NE", 90: "E", 135: "SE", 180: "S", 225: "SW", 270: "W", 315: "NW",
};

/** Wraps degrees into [0, 360). */
export function wrap360(deg: number): number {
  const d = deg % 360;
  return d < 0 ? d + 360 : d;
}

/** Signed difference a − b in (−180, 180]. */
export function diff180(a: number, b: number): number {
  let d = wrap360(a - b);
  if (d > 180) d -= 360;
  return d;
}

/**
 * Ticks every `step` degrees within ±span/2 of `heading`; majors every 15° (labelled: cardinal
 * points by name, the others by number). A major within `labelMargin` degrees of either edge
 * has no label: its text, centred on the tick, would be cut by the tape's edge ("00" for
 * 300). Empty for a non-finite heading.
 */
export function compassTicks(heading: number, span = 120, step = 5, labelMargin = 0): CompassTick[] {
  if (!Number.isFinite(heading) || span <= 0 || step <= 0) return [];
  const half = span / 2;
  const first = Math.ceil((heading - half) / step) * step;
  const ticks: CompassTick[] = [];
  for (let raw = first; raw <= heading + half + 1e-9; raw += step) {
    const deg = wrap360(Math.round(raw * 1000) / 1000);
    const major = Math.round(deg) % 15 === 0 && Math.abs(deg - Math.round(deg)) < 1e-9;
    const fits = Math.abs(raw - heading) <= half - labelMargin;
    const label = major && fits ? (CARDINALS[Math.round(deg)] ?? String(Math.round(deg))) : null;
    ticks.push({ deg, offset: raw - heading, major, label });
  }
  return ticks;
}

/**
 * Where the autopilot's heading bug goes on a tape of `span` degrees: its offset from the
 * centre, clamped to the edge (`clamped`: the setpoint is off the tape) — null without a
 * setpoint.
 */
export function bugPosition(
  heading: number,
  setpoint: number | null,
  span = 120,
): { readonly offset: number; readonly clamped: boolean } | null {
  if (setpoint === null || !Number.isFinite(setpoint) || !Number.isFinite(heading)) return null;
  const d = diff180(setpoint, heading);
  const half = span / 2;
  return Math.abs(d) > half ? { offset: Math.sign(d) * half, clamped: true } : { offset: d, clamped: false };
}
