/**
 * Unit conversion and number formatting for display. The wire and all computation use SI units
 * (m, m/s, rad); degrees appear only here, at the edge of the view.
 */

const TWO_PI = 2 * Math.PI;

export function radToDeg(rad: number): number {
  return (rad * 180) / Math.PI;
}

export function degToRad(deg: number): number {
  return (deg * Math.PI) / 180;
}

/** Wraps an angle in radians into [0, 2π). */
export function wrapTwoPi(rad: number): number {
  const r = rad % TWO_PI;
  return r < 0 ? r + TWO_PI : r;
}

/**
 * Heading in degrees rounded to 0.1 and wrapped into [0, 359.9]: 2π − ε shows as 0.0, never
 * 360.0; negative headings wrap. Non-finite input gives NaN.
 */
export function headingDeg(rad: number): number {
  if (!Number.isFinite(rad)) return Number.NaN;
  const tenths = Math.round(radToDeg(wrapTwoPi(rad)) * 10) % 3600;
  return tenths / 10;
}

/** Heading as text with one decimal, "0.0".."359.9"; "—" when unknown. */
export function formatHeading(rad: number): string {
  const deg = headingDeg(rad);
  return Number.isNaN(deg) ? PLACEHOLDER : deg.toFixed(1);
}

/** Placeholder for a value we have not received (or cannot show). */
export const PLACEHOLDER = "—";

/**
 * Fixed-point text without a negative zero ("-0.00" shows as "0.00"); `signed` adds "+" to
 * positive values so columns of commands line up. "—" for non-finite input.
 */
export function formatFixed(value: number, decimals: number, signed = false): string {
  if (!Number.isFinite(value)) return PLACEHOLDER;
  let text = value.toFixed(decimals);
  if (Number(text) === 0) text = (0).toFixed(decimals);
  return signed && Number(text) > 0 ? `+${text}` : text;
}

/** Clamps to [-1, 1] (thruster outputs and motion axes); NaN becomes 0. */
export function clampUnit(value: number): number {
  if (Number.isNaN(value)) return 0;
  return Math.min(1, Math.max(-1, value));
}
