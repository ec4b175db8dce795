/**
 * The developer page's plots as the user keeps them (pure): which plots, each a list of
 * series, stored on the server (`/api/settings/developer.plots`) so they follow the user from
 * device to device. The default set is what a developer looks at first: depth and heading,
 * each with its setpoint and estimate, the three thrusters, the voltage and the current; and,
 * for a vehicle with a position source (a DVL, a USBL, an ArduSub vehicle's own), its position
 * north and east and their 1-σ uncertainty. A series not in the telemetry yet (a setpoint
 * while its autopilot is off) is drawn as soon as it appears.
 */

import type { KeptStatus } from "../lib/kept_setting";
import type { PositionStatus } from "../lib/protocol";

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

/** What the default set adds for a vehicle with a position source. */
export const POSITION_PLOTS: PlotSet = Object.freeze([
  Object.freeze(["position.north", "position.east"]),
  Object.freeze(["position.std_north", "position.std_east"]),
]);

const WITH_POSITION: PlotSet = Object.freeze([...DEFAULT_PLOT_SET, ...POSITION_PLOTS]);

/** The default set for a vehicle with, or without, a position source. */
export function defaultPlotSet(hasPosition: boolean): PlotSet {
  return hasPosition ? WITH_POSITION : DEFAULT_PLOT_SET;
}

/** Whether telemetry's `position` says the vehicle has a position source (valid or not). */
export function hasPositionSource(position: PositionStatus | null | undefined): boolean {
  return position !== null && position !== undefined && position.sources !== null && position.sources.length > 0;
}

function samePlots(a: PlotSet, b: PlotSet): boolean {
  return a.length === b.length && a.every((p, i) => {
    const q = b[i];
    return q !== undefined && p.length === q.length && p.every((s, j) => s === q[j]);
  });
}

/**
 * The plots to show once the page learns whether the vehicle has a position source: the
 * default set for it, when the page shows the other default set unchanged and the user has no
 * set of their own (the kept setting still loading, or at its default); otherwise null (the
 * plots stay as they are — the user's own set is never changed by a vehicle).
 */
export function adaptDefaultPlots(plots: PlotSet, state: KeptStatus["state"], hasPosition: boolean): PlotSet | null {
  if (state !== "loading" && state !== "default") return null;
  return samePlots(plots, defaultPlotSet(!hasPosition)) ? defaultPlotSet(hasPosition) : null;
}

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
