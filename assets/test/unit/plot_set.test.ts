import { describe, expect, it } from "vitest";
import {
  DEFAULT_PLOT_SET,
  MAX_PLOTS,
  POSITION_PLOTS,
  adaptDefaultPlots,
  defaultPlotSet,
  encodePlotSet,
  hasPositionSource,
  parsePlotSet,
} from "../../src/developer/plot_set";
import type { PositionStatus } from "../../src/lib/protocol";

describe("developer plot set", () => {
  it("the default: depth and heading with setpoint and estimate, the three thrusters, voltage, current", () => {
    const all = DEFAULT_PLOT_SET.flat();
    for (const s of [
      "measurement.depth",
      "autopilot.depth.setpoint",
      "estimate.depth",
      "measurement.heading",
      "autopilot.heading.setpoint",
      "estimate.heading",
      "thrusters.port",
      "thrusters.vertical",
      "thrusters.starboard",
      "measurement.voltage",
      "measurement.current",
    ]) {
      expect(all).toContain(s);
    }
    expect(DEFAULT_PLOT_SET.length).toBeLessThanOrEqual(MAX_PLOTS);
  });

  it("round-trips through the server's JSON", () => {
    const plots = [["a.b", "c"], [], ["d"]];
    expect(parsePlotSet(JSON.parse(JSON.stringify(encodePlotSet(plots))))).toEqual({ ok: true, plots });
    expect(parsePlotSet(encodePlotSet(DEFAULT_PLOT_SET))).toEqual({ ok: true, plots: DEFAULT_PLOT_SET.map((p) => [...p]) });
  });

  it("a series named twice in a plot is kept once", () => {
    expect(parsePlotSet({ version: 1, plots: [["a", "a", "b"]] })).toEqual({ ok: true, plots: [["a", "b"]] });
  });

  it("refuses anything else whole, saying why", () => {
    const bad: [unknown, RegExp][] = [
      [null, /not an object/],
      [{ version: 2, plots: [] }, /unknown version/],
      [{ version: 1, plots: {} }, /not a list/],
      [{ version: 1, plots: Array.from({ length: 11 }, () => ["a"]) }, /more than 10 plots/],
      [{ version: 1, plots: ["a"] }, /plot 1 is not a list/],
      [{ version: 1, plots: [["a"], [1]] }, /plot 2: a series must be a name/],
      [{ version: 1, plots: [[""]] }, /a series must be a name/],
      [{ version: 1, plots: [Array.from({ length: 13 }, (_, i) => `s${i}`)] }, /more than 12 series/],
    ];
    for (const [value, reason] of bad) {
      const r = parsePlotSet(value);
      expect(r.ok).toBe(false);
      if (!r.ok) expect(r.reason).toMatch(reason);
    }
  });

  describe("with a position source", () => {
    const position = (sources: string[] | null): PositionStatus => ({
      valid: false,
      reason: "usbl: no report for 6.0 s",
      frame: null,
      epoch: null,
      north: null,
      east: null,
      depth: null,
      velocity_north: null,
      velocity_east: null,
      std_north: null,
      std_east: null,
      ellipse: null,
      origin: null,
      sources:
        sources === null
          ? null
          : sources.map((name) => ({
              name,
              kind: null,
              state: "waiting",
              reason: null,
              connected: false,
              reports: 0,
              accepted: 0,
              rejected: {},
              garbage: 0,
              disconnects: 0,
              reacquired: 0,
              altitude: null,
              fom: null,
              std: null,
              innovation: null,
              dead_reckoning: null,
            })),
    });

    it("the default adds position north and east and their 1-σ", () => {
      const all = defaultPlotSet(true).flat();
      for (const s of ["position.north", "position.east", "position.std_north", "position.std_east"]) expect(all).toContain(s);
      expect(defaultPlotSet(true).slice(0, DEFAULT_PLOT_SET.length)).toEqual(DEFAULT_PLOT_SET);
      expect(defaultPlotSet(true).length).toBe(DEFAULT_PLOT_SET.length + POSITION_PLOTS.length);
      expect(defaultPlotSet(true).length).toBeLessThanOrEqual(MAX_PLOTS);
      expect(defaultPlotSet(false)).toEqual(DEFAULT_PLOT_SET);
      expect(DEFAULT_PLOT_SET.flat().some((s) => s.startsWith("position."))).toBe(false);
    });

    it("a vehicle has a position source when telemetry lists one, valid or not", () => {
      expect(hasPositionSource(position(["dvl"]))).toBe(true);
      expect(hasPositionSource(position(["dvl", "usbl"]))).toBe(true);
      expect(hasPositionSource(position([]))).toBe(false);
      expect(hasPositionSource(position(null))).toBe(false);
      expect(hasPositionSource(null)).toBe(false);
      expect(hasPositionSource(undefined)).toBe(false);
    });

    it("the default plots follow the vehicle; the user's own set never changes", () => {
      const plain = DEFAULT_PLOT_SET.map((p) => [...p]);
      const withPosition = defaultPlotSet(true).map((p) => [...p]);
      // the page shows the default (loading the user's set, or there is none): it follows
      expect(adaptDefaultPlots(plain, "loading", true)).toEqual(defaultPlotSet(true));
      expect(adaptDefaultPlots(plain, "default", true)).toEqual(defaultPlotSet(true));
      expect(adaptDefaultPlots(withPosition, "default", false)).toEqual(DEFAULT_PLOT_SET);
      // already right
      expect(adaptDefaultPlots(withPosition, "default", true)).toBeNull();
      expect(adaptDefaultPlots(plain, "default", false)).toBeNull();
      // the user's: stored, being saved, saved, not kept, or not the default set
      for (const state of ["stored", "saving", "saved", "not_kept", "error"] as const) {
        expect(adaptDefaultPlots(plain, state, true)).toBeNull();
      }
      expect(adaptDefaultPlots([["measurement.depth"]], "default", true)).toBeNull();
      expect(adaptDefaultPlots([...plain, ["sim.x"]], "loading", true)).toBeNull();
      expect(adaptDefaultPlots(plain.slice(1), "loading", true)).toBeNull();
    });
  });
});
