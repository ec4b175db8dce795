/**
 * The developer page's plots as the user keeps them (pure): which plots, each a list of
 * series, stored on the server (`/api/settings/developer.plots`) so they follow the user from
 * device to device. The default set is what a developer looks at first: depth and heading,
 * each with its setpoint and estimate, the three thrusters, the voltage and the current.
 * A series not in the telemetry yet (a setpoint while its autopilot is off) is drawn as soon
 * as it appears.
 */

export const MAX_PLOTS = 10;
export const MAX_SERIES_PER_PLOT = 12;
const MAX_SERIES_NAME = 200;

export type PlotSet = readonly (readonly string[])[];

export const DEFAULT_PLOT_SET: PlotSet = Object.freeze([
  Object.freeze(["measurement.depth", "autopilot.depth.setpoint", "estimate.depth"]),
  Object.freeze(["measurement.heading", "autopilot.heading.setpoint", "estimate.heading"]),
  Object.freeze(["thrusters.port", "thrusters.vertical", "thrusters.starboard"]),
  Object.freeze(["measurement.voltage"]),
  Object.freeze(["measurement.current"]),
]);

/** The JSON kept on the server: `{"version": 1, "plots": [[series, …], …]}`. */
export function encodePlotSet(plots: PlotSet): { version: 1; plots: string[][] } {
  return { version: 1, plots: plots.map((p) => [...p]) };
}

/** A plot set from the server's JSON, or why it cannot be used (all or nothing). */
export function parsePlotSet(value: unknown): { ok: true; plots: string[][] } | { ok: false; reason: string } {
  if (typeof value !== "object" || value === null || Array.isArray(value)) return { ok: false, reason: "not an object" };
  const v = value as Record<string, unknown>;
  if (v["version"] !== 1) return { ok: false, reason: `unknown version ${JSON.stringify(v["version"])}` };
  const plots = v["plots"];
  if (!Array.isArray(plots)) return { ok: false, reason: "plots is not a list" };
  if (plots.length > MAX_PLOTS) return { ok: false, reason: `more than ${MAX_PLOTS} plots` };
  const out: string[][] = [];
  for (const [i, plot] of plots.entries()) {
    if (!Array.isArray(plot)) return { ok: false, reason: `plot ${i + 1} is not a list` };
    if (plot.length > MAX_SERIES_PER_PLOT) return { ok: false, reason: `plot ${i + 1} has more than ${MAX_SERIES_PER_PLOT} series` };
    const series: string[] = [];
    for (const s of plot) {
      if (typeof s !== "string" || s === "" || s.length > MAX_SERIES_NAME) return { ok: false, reason: `plot ${i + 1}: a series must be a name` };
      if (!series.includes(s)) series.push(s);
    }
    out.push(series);
  }
  return { ok: true, plots: out };
}
