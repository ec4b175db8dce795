/** Time-axis arithmetic of the plots (pure; seconds). */

/** Seconds shown while a plot follows live data. */
export const LIVE_WINDOW_S = 60;

/** The x range [min, max] a time window of `span` s ending at the newest sample gives. */
export function liveRange(times: readonly number[], span = LIVE_WINDOW_S): { min: number; max: number } | null {
  const last = times[times.length - 1];
  const first = times[0];
  if (last === undefined || first === undefined) return null;
  return { min: Math.max(first, last - span), max: Math.max(last, first + 1e-3) };
}

/** Zooms [min, max] by `factor` (< 1 zooms in) around `at`. */
export function zoomRange(min: number, max: number, at: number, factor: number): { min: number; max: number } {
  const a = Math.min(Math.max(at, min), max);
  return { min: a - (a - min) * factor, max: a + (max - a) * factor };
}

/** Shifts [min, max] by `fraction` of its width (positive: later). */
export function panRange(min: number, max: number, fraction: number): { min: number; max: number } {
  const d = (max - min) * fraction;
  return { min: min + d, max: max + d };
}
