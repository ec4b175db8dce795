/**
 * Plot series derived from the telemetry payload itself: every numeric (or boolean) leaf is a
 * series named by its path ("measurement.depth", "thrusters.port_us", "estimate.yaw_rate",
 * "wild_points.by_field.hdgd"…), so whatever the vehicle publishes can be plotted without the
 * page knowing it in advance. Thesis table 7.3 gives the groups and their order.
 */

/** Paths never plotted: the x axis and bookkeeping. */
const EXCLUDED = new Set(["sent_at"]);

/** Flattens the numeric and boolean leaves of a payload into `path → number`. */
export function flattenNumeric(value: unknown, prefix = "", out: Map<string, number> = new Map()): Map<string, number> {
  if (typeof value === "number") {
    if (Number.isFinite(value) && !EXCLUDED.has(prefix)) out.set(prefix, value);
  } else if (typeof value === "boolean") {
    if (!EXCLUDED.has(prefix)) out.set(prefix, value ? 1 : 0);
  } else if (typeof value === "object" && value !== null && !Array.isArray(value)) {
    for (const [key, child] of Object.entries(value as Record<string, unknown>)) {
      flattenNumeric(child, prefix === "" ? key : `${prefix}.${key}`, out);
    }
  }
  return out;
}

/** Group of a series, for the picker: thesis table 7.3's columns first, then the rest. */
export type SeriesGroup =
  | "Measurement"
  | "Command"
  | "Estimated state"
  | "Simulated state"
  | "Thrusters"
  | "Autopilot"
  | "Control"
  | "Link"
  | "Wild points"
  | "Other";

const GROUPS: readonly [string, SeriesGroup][] = [
  ["measurement.", "Measurement"],
  ["command.", "Command"],
  ["estimate.", "Estimated state"],
  ["sim.", "Simulated state"],
  ["thrusters.", "Thrusters"],
  ["autopilot.", "Autopilot"],
  ["control.", "Control"],
  ["link.", "Link"],
  ["wild_points.", "Wild points"],
];

export const GROUP_ORDER: readonly SeriesGroup[] = [
  "Measurement",
  "Command",
  "Estimated state",
  "Simulated state",
  "Thrusters",
  "Autopilot",
  "Control",
  "Link",
  "Wild points",
  "Other",
];

export function seriesGroup(path: string): SeriesGroup {
  for (const [prefix, group] of GROUPS) if (path.startsWith(prefix)) return group;
  return "Other";
}

const ANGLE_LEAVES = new Set(["heading", "roll", "pitch", "phi", "theta", "psi", "tilt"]);
const RATE_LEAVES = new Set(["yaw_rate", "p", "q", "r"]);

/** Angles are stored in rad (SI) and plotted in degrees, as the operator reads them. */
export function isAngle(path: string): boolean {
  const parts = path.split(".");
  const leaf = parts[parts.length - 1] ?? "";
  if (ANGLE_LEAVES.has(leaf) && !path.startsWith("command.")) return true;
  // autopilot.heading.setpoint
  return parts[0] === "autopilot" && parts[1] === "heading" && leaf === "setpoint";
}

export function isAngularRate(path: string): boolean {
  const leaf = path.split(".").pop() ?? "";
  return (path.startsWith("sim.") || path.startsWith("estimate.")) && RATE_LEAVES.has(leaf);
}

/** Unit shown with a series as plotted (after `displayValue`). */
export function seriesUnit(path: string): string {
  if (isAngle(path)) return "deg";
  if (isAngularRate(path)) return "deg/s";
  const leaf = path.split(".").pop() ?? "";
  if (leaf.endsWith("_us")) return "µs";
  if (path === "t") return "s";
  if (leaf === "voltage") return "V";
  if (leaf === "current" && path.startsWith("measurement.")) return "A";
  if (path.startsWith("measurement.depth") || ["x", "y", "z"].includes(leaf) || leaf === "depth") return "m";
  if (["u", "v", "w", "depth_rate"].includes(leaf)) return "m/s";
  return "";
}

/** A stored (SI) value as plotted: radians become degrees. */
export function displayValue(path: string, value: number): number {
  return isAngle(path) || isAngularRate(path) ? (value * 180) / Math.PI : value;
}

const WRAPPED_LEAVES = new Set(["heading", "psi", "phi"]);
/** One turn, in the stored unit (rad). */
const TURN = 2 * Math.PI;

/**
 * Angles kept wrapped to one turn (heading in [0, 360), psi and phi in [-180, 180)): a vehicle
 * turning through north jumps by a whole turn between two samples, and a steady heading near
 * north jitters between both ends.
 */
export function isWrappedAngle(path: string): boolean {
  if (!isAngle(path)) return false;
  const parts = path.split(".");
  const leaf = parts[parts.length - 1] ?? "";
  return WRAPPED_LEAVES.has(leaf) || (parts[0] === "autopilot" && parts[1] === "heading");
}

/** One turn in the stored unit (rad) for a wrapped angle, else null: what `unwrapNext` takes. */
export function wrapPeriod(path: string): number | null {
  return isWrappedAngle(path) ? TURN : null;
}

/**
 * `value` moved by whole turns (`period`) to lie within half a turn of `previous`: the next
 * sample of a wrapped angle on one continuous line. The first sample (no previous) stays.
 */
export function unwrapNext(previous: number | null, value: number, period: number): number {
  if (previous === null) return value;
  return value - period * Math.round((value - previous) / period);
}

/** A wrapped angle's samples as one continuous line (gaps stay gaps and do not break it). */
export function unwrap(values: readonly (number | null)[], period: number): (number | null)[] {
  let previous: number | null = null;
  return values.map((v) => {
    if (v === null) return null;
    previous = unwrapNext(previous, v, period);
    return previous;
  });
}

/**
 * Where a wrapped angle's turn starts as it reads (degrees): 0 for a heading, read in
 * [0, 360); -180 for psi and phi, read in [-180, 180). Null for a series that does not wrap.
 */
export function turnStart(path: string): number | null {
  if (!isWrappedAngle(path)) return null;
  const leaf = path.split(".").pop() ?? "";
  return leaf === "psi" || leaf === "phi" ? -180 : 0;
}

/** `degrees` moved by whole turns into [start, start + 360). */
export function intoTurn(degrees: number, start: number): number {
  const wrapped = ((((degrees - start) % 360) + 360) % 360) + start;
  return wrapped === 0 ? 0 : wrapped; // no negative zero
}

/** "measurement.depth [m]" */
export function seriesLabel(path: string): string {
  const unit = seriesUnit(path);
  return unit === "" ? path : `${path} [${unit}]`;
}

/** Thesis table 7.3's rows, in its order (then the rest of each group in payload order). */
const TABLE_ORDER: readonly string[] = [
  "measurement.depth",
  "measurement.roll",
  "measurement.pitch",
  "measurement.heading",
  "measurement.voltage",
  "measurement.current",
  "command.surge",
  "command.heave",
  "command.yaw",
  "estimate.roll",
  "estimate.pitch",
  "estimate.heading",
  "estimate.depth",
  "sim.x",
  "sim.y",
  "sim.z",
  "sim.psi",
  "sim.u",
  "sim.w",
  "sim.r",
  "thrusters.starboard",
  "thrusters.port",
  "thrusters.vertical",
];

/** Sorts series paths by group, table 7.3's rows first, the rest in payload order. */
export function sortSeries(paths: readonly string[]): string[] {
  const group = (p: string): number => GROUP_ORDER.indexOf(seriesGroup(p));
  const row = (p: string, i: number): number => {
    const r = TABLE_ORDER.indexOf(p);
    return r >= 0 ? r : TABLE_ORDER.length + i;
  };
  return paths
    .map((p, i) => ({ p, i }))
    .sort((a, b) => group(a.p) - group(b.p) || row(a.p, a.i) - row(b.p, b.i))
    .map(({ p }) => p);
}
