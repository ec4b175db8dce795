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

/**
 * Angles kept wrapped to one turn (heading in [0, 360), psi and phi in [-180, 180)): a vehicle
 * turning through north jumps by a whole turn between two samples.
 */
export function isWrappedAngle(path: string): boolean {
  if (!isAngle(path)) return false;
  const parts = path.split(".");
  const leaf = parts[parts.length - 1] ?? "";
  return WRAPPED_LEAVES.has(leaf) || (parts[0] === "autopilot" && parts[1] === "heading");
}

/**
 * Plotted values (degrees) of a wrapped angle with a gap (null) where two consecutive samples
 * differ by more than half a turn: the line breaks at north instead of crossing the whole
 * plot. The sample after the jump is dropped from the line (it is still in the CSV download).
 */
export function breakWraps(values: readonly (number | null)[]): (number | null)[] {
  const out: (number | null)[] = new Array<number | null>(values.length);
  let previous: number | null = null;
  for (let i = 0; i < values.length; i++) {
    const v = values[i] ?? null;
    out[i] = v !== null && previous !== null && Math.abs(v - previous) > 180 ? null : v;
    if (v !== null) previous = v;
  }
  return out;
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
