import { describe, expect, it } from "vitest";
import { DEFAULT_PLOT_SET, MAX_PLOTS, encodePlotSet, parsePlotSet } from "../../src/developer/plot_set";

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
});
