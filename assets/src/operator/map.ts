/**
 * The map panel's view model (pure): the vehicle's track, the map's extent and projection
 * (north up, east right, metres in the position's frame), the 1-σ ellipse in screen terms,
 * the position and its sources as a pilot reads them, and the waypoints the pilot plans.
 */

import type { DpStatus, Mission, PositionSource, PositionStatus } from "../lib/protocol";
import type { WaypointOut } from "../lib/vehicle_client";

/** A point in the position's frame (m, north and east). */
export interface MapPoint {
  readonly north: number;
  readonly east: number;
}

/** The vehicle's recent positions, in the frame of one `epoch` of the estimate. */
export interface Track {
  readonly epoch: number | null;
  readonly points: readonly MapPoint[];
}

export const NO_TRACK: Track = Object.freeze({ epoch: null, points: [] });

/** at most this many points are kept (the oldest go) */
export const TRACK_MAX = 1200;
/** a new point only once the vehicle has moved this far (m) from the last */
export const TRACK_STEP_M = 0.05;
/** at most this many waypoints in a mission (the server's limit) */
export const MAX_WAYPOINTS = 100;

/** The estimate's position, when it has one (valid or not). */
export function positionOf(p: PositionStatus | null | undefined): MapPoint | null {
  if (!p || p.north === null || p.east === null) return null;
  return { north: p.north, east: p.east };
}

/**
 * The track with the estimate `p` appended when it is valid and has moved `TRACK_STEP_M` from
 * the last point; a new frame (`epoch`) starts a new track — the old one was in other
 * coordinates.
 */
export function withTrackPoint(track: Track, p: PositionStatus | null | undefined): Track {
  if (!p || !p.valid) return track;
  const here = positionOf(p);
  if (here === null) return track;
  const epoch = p.epoch ?? null;
  if (epoch !== track.epoch) return { epoch, points: [here] };
  const last = track.points[track.points.length - 1];
  if (last !== undefined && Math.hypot(here.north - last.north, here.east - last.east) < TRACK_STEP_M) return track;
  const points = track.points.length >= TRACK_MAX ? track.points.slice(track.points.length - TRACK_MAX + 1) : track.points;
  return { epoch, points: [...points, here] };
}

/** What the map shows around: centre (m) and metres per pixel, in a `width`×`height` box (px). */
export interface MapView {
  readonly centre: MapPoint;
  /** px per metre */
  readonly scale: number;
  readonly width: number;
  readonly height: number;
  /** the grid's spacing (m) */
  readonly grid: number;
}

/** The smallest of 1, 2, 5 × 10^k at least `x`. */
export function niceStep(x: number): number {
  const p = 10 ** Math.floor(Math.log10(Math.max(x, 1e-9)));
  for (const m of [1, 2, 5, 10]) if (m * p >= x) return m * p;
  return 10 * p;
}

/**
 * A view that holds every point in `points` with a margin, at least `minSpan` m across; its
 * span and centre move in steps (a nice span, the centre on a quarter of it) so the map stands
 * still while the vehicle moves within it.
 */
export function fitView(points: readonly MapPoint[], width: number, height: number, minSpan = 10): MapView {
  const ns = points.map((p) => p.north);
  const es = points.map((p) => p.east);
  const [n0, n1] = ns.length ? [Math.min(...ns), Math.max(...ns)] : [0, 0];
  const [e0, e1] = es.length ? [Math.min(...es), Math.max(...es)] : [0, 0];
  const aspect = width / Math.max(height, 1);
  // the span across the shorter side, so both extents fit with a 20 % margin
  const needed = Math.max((n1 - n0) * 1.2, ((e1 - e0) * 1.2) / Math.max(aspect, 1e-9), minSpan);
  const span = niceStep(needed);
  const quarter = span / 4;
  const centre = { north: Math.round((n0 + n1) / 2 / quarter) * quarter, east: Math.round((e0 + e1) / 2 / quarter) * quarter };
  // rounding the centre may leave a point outside: widen once more then
  const fits = points.every((p) => Math.abs(p.north - centre.north) <= span / 2 && Math.abs(p.east - centre.east) <= (span * aspect) / 2);
  const s = fits ? span : niceStep(span * 1.01);
  return { centre, scale: height / s, width, height, grid: niceStep(s / 5) };
}

/** A map point on screen (px, y down). */
export function toScreen(view: MapView, p: MapPoint): { readonly x: number; readonly y: number } {
  return { x: view.width / 2 + (p.east - view.centre.east) * view.scale, y: view.height / 2 - (p.north - view.centre.north) * view.scale };
}

/** The map point under a screen point (px, y down). */
export function fromScreen(view: MapView, x: number, y: number): MapPoint {
  return { north: view.centre.north - (y - view.height / 2) / view.scale, east: view.centre.east + (x - view.width / 2) / view.scale };
}

/** The grid lines' positions (m) across the view: north values (horizontal lines), east values (vertical). */
export function gridLines(view: MapView): { readonly north: readonly number[]; readonly east: readonly number[] } {
  const halfN = view.height / 2 / view.scale;
  const halfE = view.width / 2 / view.scale;
  const lines = (c: number, half: number): number[] => {
    const out: number[] = [];
    for (let v = Math.ceil((c - half) / view.grid) * view.grid; v <= c + half + 1e-9; v += view.grid) out.push(Number(v.toFixed(6)));
    return out;
  };
  return { north: lines(view.centre.north, halfN), east: lines(view.centre.east, halfE) };
}

/**
 * The 1-σ ellipse on screen: centre, semi-axes (px) and the SVG rotation (degrees, clockwise
 * from the screen's x axis) of its major axis, which points `angle` rad from north towards east.
 */
export function ellipseOnScreen(
  view: MapView,
  p: PositionStatus,
): { readonly cx: number; readonly cy: number; readonly rx: number; readonly ry: number; readonly rotate: number } | null {
  const here = positionOf(p);
  if (here === null || p.ellipse === null) return null;
  const { x, y } = toScreen(view, here);
  return { cx: x, cy: y, rx: p.ellipse.major * view.scale, ry: p.ellipse.minor * view.scale, rotate: (p.ellipse.angle * 180) / Math.PI - 90 };
}

function fixed(x: number, digits: number): string {
  return (Object.is(Math.round(x * 10 ** digits), -0) ? 0 : x).toFixed(digits);
}

/** The position as the pilot reads it: where, how sure, or honestly why there is none. */
export function positionText(p: PositionStatus | null | undefined): { readonly valid: boolean; readonly text: string } {
  if (!p) return { valid: false, text: "No position: the server sends none" };
  const here = positionOf(p);
  if (!p.valid) return { valid: false, text: `No position: ${p.reason ?? "not valid"}` };
  if (here === null) return { valid: false, text: "No position" };
  const sigma = p.ellipse ? ` ± ${fixed(p.ellipse.major, 2)} m` : "";
  return { valid: true, text: `N ${fixed(here.north, 2)} m, E ${fixed(here.east, 2)} m${sigma} (${p.frame ?? "?"} frame)` };
}

/** One source's line: its state, what it measures now, and why it is not valid. */
export function sourceText(s: PositionSource): string {
  const details: string[] = [];
  if (s.altitude !== null && s.altitude >= 0) details.push(`altitude ${fixed(s.altitude, 1)} m`);
  if (s.std !== null) details.push(`σ ${fixed(s.std, 2)} m`);
  if (s.garbage !== null && s.garbage > 0) details.push(`${s.garbage} unreadable`);
  const rejected = s.rejected ? Object.values(s.rejected).reduce((a, b) => a + b, 0) : 0;
  if (rejected > 0) details.push(`${rejected} rejected`);
  const head = `${s.name}: ${s.state}${details.length ? ` (${details.join(", ")})` : ""}`;
  return s.reason ? `${head} — ${s.reason}` : head;
}

/** Every point the map should hold: the track, the vehicle, DP's target, the mission and the plan. */
export function pointsOnMap(
  track: Track,
  position: PositionStatus | null | undefined,
  dp: DpStatus | null | undefined,
  mission: Mission | null,
  plan: readonly MapPoint[],
): MapPoint[] {
  const out: MapPoint[] = [...track.points];
  const here = positionOf(position);
  if (here) out.push(here);
  if (dp && dp.x !== null && dp.y !== null) out.push({ north: dp.x, east: dp.y });
  if (mission) out.push(...mission.waypoints);
  out.push(...plan);
  return out;
}

/** The planned points as waypoints at `depth` (m), to send with `start`. */
export function planWaypoints(plan: readonly MapPoint[], depth: number): WaypointOut[] {
  const d = Math.max(0, Math.round(depth * 10) / 10);
  return plan.map((p) => ({ north: Math.round(p.north * 100) / 100, east: Math.round(p.east * 100) / 100, depth: d }));
}

/** The depth new waypoints take: the depth autopilot's setpoint, else the depth estimate, else null. */
export function planDepth(depthSetpoint: number | null | undefined, depthEstimate: number | null | undefined): number | null {
  if (depthSetpoint !== null && depthSetpoint !== undefined && Number.isFinite(depthSetpoint)) return depthSetpoint;
  if (depthEstimate !== null && depthEstimate !== undefined && Number.isFinite(depthEstimate)) return depthEstimate;
  return null;
}
